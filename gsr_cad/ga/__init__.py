"""Problem-agnostic genetic algorithm engine: genes are opaque hashable items."""
