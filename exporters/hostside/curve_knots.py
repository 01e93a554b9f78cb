"""Knot vectors and Bezier pieces of gsr_cad's curve forms in plain Python, for the host scripts.

The FreeCAD macro and the Blender curve script rebuild the curve from their own replay of the history, so
they check its ops where gsr_cad's rules allow them and compute its knots themselves. gsr_cad's literal encoder copies the code below into each of them in place
of their line ``from curve_knots import ...  # gsr:inline`` (:func:`gsr_cad.exporters.encode.fill_python`);
the scripts stay self-contained, and gsr_cad's tests hold this code to ``gsr_cad.geometry.bspline``.
"""


def check_index(op, index, n, closed):
    """ValueError unless `index` is where the curve op `op` may apply on n points, by gsr_cad's rules: an
    insertion becomes points[index] for 1 <= index <= n - 1 (closed: <= n); a move keeps an open curve's ends
    (1 <= index <= n - 2; closed: any point)."""
    if op == "add_point":
        lo, hi = 1, n if closed else n - 1
    else:
        lo, hi = (0, n - 1) if closed else (1, n - 2)
    if not lo <= index <= hi:
        raise ValueError("%s index %d outside [%d, %d]" % (op, index, lo, hi))


def with_corner(corners, index, n, k, closed):
    """The corners, sorted, with points[index] made a C0 corner (an interior knot of multiplicity k); ValueError
    where gsr_cad allows none: an index already a corner, off the points (an open curve's: k points from
    either end), or fewer than k points from another corner (across the seam of a closed curve)."""
    out = sorted(set(corners) | {index})
    lo, hi = (0, n - 1) if closed else (k, n - 1 - k)
    gaps = [b - a for a, b in zip(out, out[1:] + ([out[0] + n] if closed else []))]
    if index in corners or not lo <= index <= hi or (gaps and min(gaps) < k):
        raise ValueError("corner %d not allowed with corners %s on %d points of degree %d"
                         % (index, sorted(corners), n, k))
    return out


def form_knots(n, k, closed, corners, spare=0):
    """The knot vector of n control points of degree k, each corner i merging the knots t[i+1] .. t[i+k] into
    one, distinct knots evenly spaced: clamped on [0, 1] (n + k + 1 knots), or periodic with period 1 and
    t[k] = 0 (n + 2k + 1 knots, and `spare` more periods of k knots at the end)."""
    merged = set(j for i in corners for j in range(i + 2, i + k + 1))
    if not closed:
        inner, g = [], 0
        for j in range(k + 1, n):
            g += j not in merged
            inner.append(g)
        return [0.0] * (k + 1) + [x / (g + 1) for x in inner] + [1.0] * (k + 1)
    merged = set(m % n for m in merged)
    starts, g = [], 0
    for j in range(k, k + n):
        g += (j % n) not in merged
        starts.append(g)
    period = [(x - starts[0]) / starts[-1] for x in starts]
    return [period[(j - k) % n] + (j - k) // n for j in range(n + (2 + spare) * k + 1)]


def distinct(knots):
    """The distinct values of a knot vector and their multiplicities."""
    values, mults = [], []
    for u in knots:
        if values and u == values[-1]:
            mults[-1] += 1
        else:
            values.append(u)
            mults.append(1)
    return values, mults


def periodic_form(points, k, corners):
    """(poles, distinct knots, multiplicities) of a closed curve as one period [0, 1] of a periodic B-spline
    (end multiplicities equal: the number of knots at 0); the poles are turned by the copies of the knot at 0
    after t[k]."""
    t = form_knots(len(points), k, True, corners)
    knots, mults = distinct(t[k:k + len(points) + 1])
    zeros = [j for j, u in enumerate(t) if u == 0.0]
    mults[0] = mults[-1] = len(zeros)
    shift = zeros[-1] - k
    return list(points[shift:]) + list(points[:shift]), knots, mults


def bezier_pieces(points, k, closed, corners):
    """The exact Bezier pieces (k + 1 points each, one per knot span on [0, 1]) of the curve: Boehm knot
    insertion until every knot in [0, 1] has multiplicity k."""
    n = len(points)
    t = form_knots(n, k, closed, corners, spare=1)
    c = [tuple(float(x) for x in points[j % n]) for j in range(len(t) - k - 1)]
    for u in sorted(set(x for x in t if 0.0 <= x <= 1.0)):
        while sum(1 for x in t if x == u) < k:
            s = max(i for i in range(len(t) - 1) if t[i] <= u < t[i + 1])
            new = []
            for i in range(s - k + 1, s + 1):
                a = (u - t[i]) / (t[i + k] - t[i])
                new.append(tuple((1.0 - a) * p + a * q for p, q in zip(c[i - 1], c[i])))
            c[s - k + 1:s] = new
            t.insert(s + 1, u)
    return [c[s - k:s + 1] for s in range(k, len(t) - k - 1) if 0.0 <= t[s] < t[s + 1] <= 1.0]
