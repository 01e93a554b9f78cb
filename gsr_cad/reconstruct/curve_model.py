"""The structure search behind the Lamarckian curve evaluation: segments between corners and their counts.

A curve structure is a set of corners (data points where the curve is only C0) and a number of control
points per *segment* (the data between two consecutive corners, or the ends). Corners are knots of
multiplicity ``degree`` and distinct knots are evenly spaced, so the whole curve is exactly the chain of
clamped uniform B-splines fitted to the segments one by one (a closed curve without corners is one
periodic uniform B-spline). Each segment fit is a least-squares placement with foot-point correction,
cached per ``(segment, count)``; its error is measured both ways: data -> curve (foot points) and
curve -> data (curve samples per span and between neighbouring foot points, against the data's polyline),
so a curve cannot make a loop or bridge a gap far from the data.

With a max-distance tolerance ``X`` each segment gets the fewest control points whose two-sided max
distance is within ``X`` (exponential then bisection search, or a gallop from its parts' counts for a merged
segment; no fixed cap below the segment's point count; the data's model is sharp at every corner candidate);
without one, points go one at a time to the segment whose squared error drops most and the total count
minimises the BIC-like cost of :mod:`gsr_cad.reconstruct.curve`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.special import fdtrc  # the F distribution's survival function (scipy.stats takes 0.5 s to import)

from ..geometry import bspline
from ..geometry.curvefit import CurveFit, fit_curve, minimax_refine, tangent_refine, warp_basis, warped_fit
from ..geometry.distance import curve_to_points, data_model, spline_foot_points
from .config import CurveConfig

Key = tuple[int, int]  # a segment: search-point indices (first, last), last may exceed the count (wraps, closed)
PERIODIC: Key = (-1, -1)  # the whole closed curve as one periodic segment
SMALL_COUNT = 8  # a tolerance search tries every count below this: a B-spline's exact count may lie between misses
WARP_TERMS = 4  # the most warp terms of the sampling model (u = s^2 needs one)
BIC_TIE = 2.0  # BIC differences below this are no evidence (Kass and Raftery): the fewer warp terms win
NOISE_RATIO = 4.0  # residuals whose squared RMS exceeds this many noise variances are model error, not noise
SAMPLING_ALPHA = 0.01  # significance level at which the sampling model is rejected against free foot points


@dataclasses.dataclass(frozen=True)
class SegmentFit:
    """One segment's fit and its errors (absolute distances)."""

    fit: CurveFit
    sse: float
    data_max: float
    curve_max: float
    allowance: float

    @property
    def both_max(self) -> float:
        return max(self.data_max, self.curve_max)


@dataclasses.dataclass(frozen=True)
class SamplingChoice:
    """The outcome of :meth:`CurveModel.sampling`: the count and fit taken, and the test that decided."""

    fit: CurveFit
    count: int
    free_count: int
    terms: int
    f_stat: float
    p_value: float
    accepted: bool


def _noise_variance(points: np.ndarray) -> float:
    """The data's noise variance per coordinate, without a model: the mean square of the normalised fourth
    differences (``(1, -4, 6, -4, 1) / sqrt(70)``: unit variance on white noise; a smooth curve's part is of
    the order of the sample spacing to the fourth, far below)."""
    diff = np.diff(points, n=4, axis=0) / math.sqrt(70.0)
    return float(np.mean(diff ** 2)) if len(diff) else 0.0


class CurveModel:
    """Segment fits and counts for one (search) point set."""

    def __init__(self, points: np.ndarray, closed: bool, candidates: np.ndarray, config: CurveConfig,
                 degree: int, diag: float, limit: float | None, lo: np.ndarray, hi: np.ndarray,
                 sharp: np.ndarray | None = None, full: np.ndarray | None = None, search: np.ndarray | None = None):
        self.points, self.closed, self.config, self.degree = points, closed, config, degree
        self.sharp = np.zeros(0, dtype=np.int64) if sharp is None else np.asarray(sharp, dtype=np.int64)
        self.candidates = np.asarray(candidates, dtype=np.int64)
        self.m = len(points)
        self.diag, self.limit, self.lo, self.hi = diag, limit, lo, hi
        self._fits: dict[tuple[Key, int], SegmentFit] = {}
        self._models: dict[Key, np.ndarray] = {}
        self._densified: set[Key] = set()  # segments fitted to their data model (the limit was out of reach)
        self.full, self.search = full, search  # all the data, and the search points' indices into them
        self._all: set[Key] = set()  # segments fitted to all their data points (see use_all)
        self._need: dict[Key, int] = {}
        self._lower: dict[Key, int] = {}  # proven lower bounds of need()
        self.upto: int | None = None  # the best known total: segments needing more are not searched further
        self._alloc: dict[tuple[int, ...], list[tuple[int, ...]]] = {}

    # --- segments --------------------------------------------------------------------------------------------
    def segments(self, corners: tuple[int, ...]) -> list[Key]:
        """Segments of a corner set (search-point indices, sorted)."""
        if not corners:
            return [PERIODIC] if self.closed else [(0, self.m - 1)]
        if self.closed:
            ends = list(corners) + [corners[0] + self.m]
            return list(zip(ends[:-1], ends[1:]))
        ends = [0, *corners, self.m - 1]
        return list(zip(ends[:-1], ends[1:]))

    def segment_points(self, key: Key) -> np.ndarray:
        """The segment's search points, or all its data points once :meth:`use_all` was called for it."""
        if key in self._all:
            return self.full[self._full_range(key)]
        if key == PERIODIC:
            return self.points
        return self.points[np.arange(key[0], key[1] + 1) % self.m]

    def _full_range(self, key: Key) -> np.ndarray:
        """Indices into :attr:`full` of the data points of segment ``key`` (its ends included)."""
        total = len(self.full)
        if key == PERIODIC:
            return np.arange(total)
        a = int(self.search[key[0] % self.m])
        b = int(self.search[key[1] % self.m]) + (total if key[1] >= self.m else 0)
        return np.arange(a, b + 1) % total

    def use_all(self, key: Key) -> bool:
        """Fit segment ``key`` to all its data points from now on (a subsampled search missed between its
        points); False when there is nothing more to use."""
        if self.full is None or key in self._all or len(self._full_range(key)) <= len(self.segment_points(key)):
            return False
        self._all.add(key)
        self._densified.discard(key)
        self._forget(key)
        return True

    def min_count(self, key: Key) -> int:
        """One span per segment; a closed curve with a single corner needs one point more (it wraps)."""
        if self.closed and key != PERIODIC and key[1] - key[0] == self.m:
            return self.degree + 2
        return self.degree + 1

    def max_count(self, key: Key) -> int:
        """No fixed cap below what the data can support: two thirds of the segment's points (nearer to
        interpolation the placement is ill-posed), or the user's cap."""
        size = len(self.segment_points(key))
        if key in self._densified:
            size *= 4
        cap = max(self.degree + 1, (2 * size) // 3)
        return min(cap, self.config.max_control_points) if self.config.max_control_points else cap

    def _inner_candidates(self, key: Key) -> np.ndarray:
        """Corner candidates inside segment ``key``, as indices into :meth:`segment_points`: the data's model is
        sharp there whether or not the curve makes them corners (as in the final check on all points)."""
        if key in self._all:
            where = self._full_range(key)
            return np.flatnonzero(np.isin(where, self.search[self.candidates]))
        if key == PERIODIC:
            return self.candidates
        rel = np.mod(self.candidates - key[0], self.m)
        return rel[(rel > 0) & (rel < key[1] - key[0])]

    def _fit_points(self, key: Key) -> np.ndarray:
        """The segment's points, densified along the polyline when it has too few for a well-posed fit, or
        sampled on the data model when the data alone are too coarse for the limit (see :meth:`need`)."""
        pts = self.segment_points(key)
        if key in self._densified:
            dense = data_model(pts, key == PERIODIC, self._inner_candidates(key), per_segment=4)
            return dense[:-1] if key == PERIODIC else dense
        while len(pts) < 2 * (self.degree + 2) and key != PERIODIC:
            mid = 0.5 * (pts[:-1] + pts[1:])
            pts = np.insert(pts, np.arange(1, len(pts)), mid, axis=0)
        return pts

    def fit(self, key: Key, n: int) -> SegmentFit:
        """Least-squares fit of ``n`` control points to segment ``key`` (cached), with its two-sided errors."""
        cached = self._fits.get((key, n))
        if cached is not None:
            return cached
        closed = key == PERIODIC
        pts = self._fit_points(key)
        warm = None
        if self.config.fitness == "geometric":
            near = [c for (k, c) in self._fits if k == key and c < n]
            warm = self._fits[(key, max(near))].fit.params if near else None
        # Parameter correction converges linearly, slowest on sparse data; without a limit (where the count is
        # the BIC's) small segments get four times the rounds and a joint step (an unconverged fit of the true
        # count would lose to more points). With a limit the minimax step follows instead.
        rounds = self.config.fit_iterations * (4 if len(pts) <= 400 and self.limit is None else 1)
        limit = self.limit
        # A tolerance search asks whether n points can meet the limit: settled once well within it (0.6: a looser
        # stop leaves fits whose curve side or warm-started successors miss) or far above it. Not on a subsample:
        # there the final check refits on all points, and fits stopped early cost points there.
        bracket = None if limit is None or self.full is not None else (0.6 * limit * self.diag,
                                                                       4.0 * limit * self.diag)
        fit = fit_curve(pts, n, self.degree, parametrization=self.config.fitness, iterations=rounds, lo=self.lo,
                        hi=self.hi, warm_params=warm, closed=closed, joint=limit is None, bracket=bracket)
        if limit is not None and limit < fit.distances.max() / self.diag < 3 * limit:
            fit = minimax_refine(pts, fit, self.degree, lo=self.lo, hi=self.hi,  # a tolerance is a maximum
                                 goal=0.9 * limit * self.diag)
        out = self._measure(key, pts, fit)
        self._fits[(key, n)] = out
        return out

    def _measure(self, key: Key, pts: np.ndarray, fit: CurveFit) -> SegmentFit:
        closed = key == PERIODIC
        model = self._models.get(key)
        if model is None:  # the data's local model, sharp at the segment's ends and at the candidates inside it
            model = self._models[key] = data_model(self.segment_points(key), closed, self._inner_candidates(key))
        spline = bspline.make_spline(fit.ctrl, self.degree, closed)
        u = np.sort(fit.params)
        mids = 0.5 * (u[:-1] + u[1:])
        if closed:
            mids = np.concatenate([mids, [np.mod(0.5 * (u[-1] + u[0] + 1.0), 1.0)]])
        back = curve_to_points(spline, pts, closed, per_span=16, extra=mids, model=model)
        gaps = np.linalg.norm(np.diff(np.vstack([pts, pts[:1]]) if closed else pts, axis=0), axis=1)
        return SegmentFit(fit, float(np.sum(fit.distances ** 2)), float(fit.distances.max()), float(back.max()),
                          0.5 * float(gaps.max()))

    def refined(self, key: Key, n: int) -> CurveFit:
        """The segment's fit of ``n`` points refined to convergence (for the winner only)."""
        quick = self.fit(key, n)
        if self.config.fitness != "geometric":
            return quick.fit
        pts = self._fit_points(key)
        fit = fit_curve(pts, n, self.degree, parametrization="geometric", iterations=60, lo=self.lo, hi=self.hi,
                        rtol=1e-7, warm_params=quick.fit.params, closed=key == PERIODIC)
        limit = self.limit
        if limit is None:  # alternating correction stops 1-10 % above the optimum of noisy data: finish it, unless
            tuned = tangent_refine(pts, fit, self.degree, lo=self.lo, hi=self.hi)  # the curve leaves the data for it
            if self._measure(key, pts, tuned).curve_max <= self._measure(key, pts, fit).curve_max * (1 + 1e-3):
                fit = tuned

        def rank(f: CurveFit) -> tuple[bool, float]:
            if limit is None:
                return False, f.rms
            return self._measure(key, pts, f).both_max / self.diag > limit, f.rms

        return min((fit, quick.fit), key=rank)

    def _free_ends(self, pts: np.ndarray, fit: CurveFit) -> CurveFit:
        return tangent_refine(pts, fit, self.degree, lo=self.lo, hi=self.hi, free_ends=True)

    def sampling(self, key: Key, n_free: int) -> SamplingChoice | None:
        """The count of a noisy open curve when its samples are evenly spaced in parameter up to a smooth warp.

        The free model (every sample's foot-point parameter an unknown, the BIC-like count ``n_free``) cannot
        separate counts near the noise's detection limit (a 12-point curve at 0.7 % noise: 9 and 12 points are
        within the likelihood ratio's reach). When the samples are evenly spaced in the curve's parameter (the
        paper's index-wise correspondence) that spacing is information too. Decision rule:

        1. *Sampling model*: sample ``i`` is matched to the curve at ``s_i + W(s_i) c`` (:func:`warped_fit`,
           ``terms = 0..WARP_TERMS`` warp coefficients ``c``, every control point free, ends included). Its
           residuals are the full 2D/3D offsets of independent samples, so an ordinary BIC applies:
           ``m d ln(RSS / m) + (n d + terms) ln(m d)`` (``d`` coordinates; RSS per point floored at the cost's
           ``tolerance``) picks ``(n, terms)``. The terms are nuisance parameters nested in each other, with
           evenly spaced samples (the paper's assumption) the simplest: the fewest terms whose best BIC is within
           ``BIC_TIE`` of the least are taken, with their best count (a warp can trade for control points at
           the noise's detection limit, and a BIC difference below 2 is no evidence either way).
        2. *Test*: the sampling model is nested in the free model with the same ``n`` and free ends (the warped
           parameters are one choice of the free ones). Under the sampling model, with Gaussian noise,
           ``F = ((RSS_w - RSS_free) / (m - 2 - terms)) / (RSS_free / (m d - n d - (m - 2)))`` follows an
           F distribution; the sampling model is rejected when its p-value is below ``SAMPLING_ALPHA``
           (samples thinned at random, bunched unevenly, or arc-length spaced along a curve whose warp the
           terms cannot follow).
        3. Accepted: ``n`` points placed by the sampling model (its maximum-likelihood curve, which uses the
           spacing: closer to the noise-free curve than the free model's); rejected: ``n_free`` points, the free
           model's least squares with free end control points. Either way the noisy end samples do not pin the
           curve's ends.

        None (the free model's fit stands) on exact data (RMS within the tolerance), on residuals that are model
        error rather than noise (their squared RMS per normal coordinate above ``NOISE_RATIO`` times the data's
        difference-based noise variance: smooth curves that are not B-splines leave 200-6000 times it, noisy
        B-splines about 1), closed curves, subsampled searches (their points are not evenly spaced by index)
        and too few points for the test.
        """
        if key == PERIODIC or self.closed or self.full is not None or key in self._densified:
            return None
        pts = self.segment_points(key)
        m, dim = pts.shape
        floor = max(self.config.tolerance, 1e-9) * self.diag
        base = self.refined(key, n_free)
        if base.rms <= floor or m < 40 or base.rms ** 2 > NOISE_RATIO * (dim - 1) * _noise_variance(pts):
            return None
        top = min(self.max_count(key), 2 * n_free + 2)
        lo = self.min_count(key)
        warp = warp_basis(m, WARP_TERMS)
        s = np.linspace(0.0, 1.0, m)
        guess = np.linalg.lstsq(warp, np.sort(base.params) - s, rcond=None)[0]  # the free fit's warp

        def bic(sse: float, n: int, terms: int) -> float:
            return m * dim * math.log(max(sse / m, floor ** 2)) + (n * dim + terms) * math.log(m * dim)

        scores: dict[tuple[int, int], tuple[float, CurveFit]] = {}
        prev: list[np.ndarray] = [np.zeros(0)] * (WARP_TERMS + 1)
        for n in range(lo, top + 1):
            coef = np.zeros(0)
            for terms in range(WARP_TERMS + 1):
                fit, coef = warped_fit(pts, n, terms, self.degree, starts=(coef, prev[terms], guess[:terms]))
                prev[terms] = coef
                scores[(n, terms)] = (bic(float(np.sum(fit.distances ** 2)), n, terms), fit)
            if min(scores, key=lambda nk: scores[nk][0])[0] + 4 < n:  # four counts past the best: it only grows
                break
        least = min(v[0] for v in scores.values())
        terms = min(k for (_, k), v in scores.items() if v[0] <= least + BIC_TIE)
        n = min((c for c, k in scores if k == terms), key=lambda c: scores[(c, terms)][0])
        warped = scores[(n, terms)][1]
        df1, df2 = m - 2 - terms, m * dim - n * dim - (m - 2)
        if df2 < 10:
            return None
        spline = bspline.make_spline(warped.ctrl, self.degree, False)
        params, dist = spline_foot_points(spline, pts, warped.params, iterations=2, periodic=False)
        starts = [CurveFit(warped.ctrl, params, dist, False)]
        if n <= self.max_count(key):
            starts.append(self.refined(key, n))
        free = min((self._free_ends(pts, f) for f in starts), key=lambda f: f.rms)
        sse_w, sse_f = float(np.sum(warped.distances ** 2)), float(np.sum(free.distances ** 2))
        f_stat = max(0.0, (sse_w - sse_f) / df1) / max(sse_f / df2, 1e-300)
        p_value = float(fdtrc(df1, df2, f_stat))
        accepted = p_value >= SAMPLING_ALPHA
        chosen = warped if accepted else self._free_ends(pts, base)
        return SamplingChoice(chosen, n if accepted else n_free, n_free, terms, f_stat, p_value, accepted)

    # --- counts ----------------------------------------------------------------------------------------------
    def meets(self, key: Key, n: int, limit: float) -> bool:
        return self.fit(key, n).both_max / self.diag <= limit

    def bound(self, key: Key, n: int) -> None:
        """Take ``n`` as a lower bound of segment ``key``'s need (e.g. the count that missed on fewer points)."""
        self._lower[key] = max(self._lower.get(key, 0), int(n))

    def need(self, key: Key, limit: float, upto: int | None = None) -> int:
        """Fewest control points meeting ``limit`` both ways (the most allowed when none does).

        With ``upto`` the search stops beyond it and returns ``upto + 1`` when ``upto`` points do not suffice
        (a lower bound, remembered as such), so a hopeless segment costs few fits.
        """
        if key in self._need:
            return self._need[key]
        lo, top = self.min_count(key), self.max_count(key)
        bounded = upto is not None
        if upto is not None:
            upto = min(upto, top)
        bound = self._lower.get(key, lo)
        if upto is not None and bound > upto:
            return bound
        if upto is not None and (self._spans_sharp(key) or not self.meets(key, upto, limit)):
            self._lower[key] = upto + 1  # one fit settles a segment that cannot beat the best known total
            return upto + 1
        if bound == lo and self.meets(key, lo, limit):
            self._need[key] = lo
            return lo
        bad, n = max(lo, bound - 1), max(lo, bound - 1)
        guess = self._guess(key)
        step = 0
        if guess is not None and bad < guess < (top if upto is None else upto):
            # A merge of two segments needs about what its parts needed together: gallop from there.
            if self.meets(key, guess, limit):
                good, gap = guess, 1
                while good - gap > bad:
                    if not self.meets(key, good - gap, limit):
                        bad = good - gap
                        break
                    good, gap = good - gap, 2 * gap
                return self._bisect(key, limit, bad, good)
            bad = n = guess
            step = 1
        while True:  # grow by one, then by half (or gallop from a guess) until met, then bisect miss and hit
            n = min(top, n + step if step else n + 1 if n < SMALL_COUNT else int(math.ceil(n * 1.5)))
            step *= 2
            if upto is not None and n > upto:
                if bad < upto and not self.meets(key, upto, limit):
                    bad = upto
                if bad >= upto:
                    self._lower[key] = upto + 1
                    return upto + 1
                n = upto
            if self.meets(key, n, limit):
                break
            bad = n
            if n >= top and key not in self._densified and not bounded:
                # Coarse data: between samples the curve cannot follow both the points and their model.
                # Fit the model's samples instead (they include the points) and search again.
                self.densify(key)
                return self.need(key, limit, upto)
            if n >= top:  # the limit is out of reach: the tried count that came closest
                tried = [c for (k, c) in self._fits if k == key]
                best = min(tried, key=lambda c: (self._fits[(key, c)].both_max, c))
                self._need[key] = best
                return best
        return self._bisect(key, limit, bad, n)

    def _bisect(self, key: Key, limit: float, bad: int, good: int) -> int:
        """The fewest count in ``(bad, good]`` meeting ``limit`` (``good`` does, ``bad`` does not), remembered."""
        while good - bad > 1:
            mid = (good + bad) // 2
            if self.meets(key, mid, limit):
                good = mid
            else:
                bad = mid
        self._need[key] = good
        return good

    def _guess(self, key: Key) -> int | None:
        """The counts two known segments that make up ``key`` needed together (they share a point), if any."""
        if key == PERIODIC or key in self._all:
            return None
        a, c = key
        for (k0, k1), n0 in self._need.items():
            if k0 == a and k1 < c and (k1, c) in self._need:
                return n0 + self._need[(k1, c)] - 1
        return None

    def densify(self, key: Key) -> bool:
        """Fit segment ``key`` to its data model's samples from now on (the points alone are too coarse for the
        limit); False when it already is."""
        if key in self._densified:
            return False
        self._densified.add(key)
        self._forget(key)
        return True

    def _forget(self, key: Key) -> None:
        for stale in [fk for fk in self._fits if fk[0] == key]:
            del self._fits[stale]
        self._models.pop(key, None)
        self._lower.pop(key, None)
        self._need.pop(key, None)
        self._alloc.clear()

    def _spans_sharp(self, key: Key) -> bool:
        """Whether a sharp candidate (turning twice the corner angle) lies strictly inside the segment: smoothing
        such a kink within a tolerance takes more points than any structure that keeps it (pruned unfitted)."""
        if key == PERIODIC:
            return self.sharp.size > 0
        inside = (self.sharp > key[0]) & (self.sharp < key[1])
        inside |= (self.sharp + self.m > key[0]) & (self.sharp + self.m < key[1])
        return bool(inside.any())

    def allocation(self, corners: tuple[int, ...], n: int) -> tuple[int, ...] | None:
        """Counts per segment for a total of ``n`` control points (None when ``n`` is too few).

        The smallest allocation meets the tolerance segment by segment (with a limit) or gives every segment
        its minimum; each further point goes to the segment whose squared error drops most.
        """
        keys = self.segments(corners)
        seq = self._alloc.get(corners)
        if seq is None:
            if self.limit is not None:
                start = tuple(self.need(k, self.limit, self.upto) for k in keys)
                if self.upto is not None and any(c > self.upto for c in start):
                    return None  # hopeless against the best known structure (not remembered: bounds may change)
            else:
                start = tuple(self.min_count(k) for k in keys)
            seq = self._alloc[corners] = [start]
        base = self.chain_total(keys, seq[0])
        if n < base:
            return None
        while base + len(seq) - 1 < n:
            counts = list(seq[-1])
            gains = []
            for i, key in enumerate(keys):
                if counts[i] >= self.max_count(key):
                    gains.append(-math.inf)
                    continue
                gains.append(self.fit(key, counts[i]).sse - self.fit(key, counts[i] + 1).sse)
            best = int(np.argmax(gains))
            if not math.isfinite(gains[best]):
                return None
            counts[best] += 1
            seq.append(tuple(counts))
        return seq[n - base]

    def chain_total(self, keys: list[Key], counts: tuple[int, ...]) -> int:
        """Control points of the curve made of segments ``keys`` with ``counts``."""
        if keys == [PERIODIC]:
            return int(counts[0])
        shared = len(keys) if self.closed else len(keys) - 1
        return int(sum(counts)) - shared

    def minimum_total(self, corners: tuple[int, ...]) -> int | None:
        """Fewest control points of a corner set (each segment at its minimum, or meeting the limit); None when
        a segment alone would need more than :attr:`upto`."""
        self.allocation(corners, 0)
        seq = self._alloc.get(corners)
        return None if seq is None else self.chain_total(self.segments(corners), seq[0])

    def errors(self, corners: tuple[int, ...], counts: tuple[int, ...]) -> tuple[float, float, float]:
        """``(rms, two-sided max, excursion beyond half the largest data gap)`` over the diagonal."""
        fits = [self.fit(k, c) for k, c in zip(self.segments(corners), counts)]
        rms = math.sqrt(sum(f.sse for f in fits) / self.m) / self.diag
        both = max(f.both_max for f in fits) / self.diag
        excess = max(max(0.0, f.curve_max - f.allowance) for f in fits) / self.diag
        return rms, both, excess

    # --- assembly --------------------------------------------------------------------------------------------
    def assemble(self, corners: tuple[int, ...], counts: tuple[int, ...], refine: bool = False
                 ) -> tuple[np.ndarray, tuple[int, ...]]:
        """Control points and corner indices of the whole curve (closed with corners: starts at the first)."""
        keys = self.segments(corners)
        ctrls = [(self.refined(k, c) if refine else self.fit(k, c).fit).ctrl for k, c in zip(keys, counts)]
        if keys == [PERIODIC]:
            return ctrls[0], ()
        chain = [ctrls[0]] + [c[1:] for c in ctrls[1:]]
        ctrl = np.vstack(chain)
        joins = np.cumsum([len(c) - 1 for c in ctrls])
        if self.closed:
            return ctrl[:-1], (0, *(int(j) for j in joins[:-1]))
        return ctrl, tuple(int(j) for j in joins[:-1])
