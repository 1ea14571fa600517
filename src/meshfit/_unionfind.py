"""Disjoint sets (union-find) over ``0 .. n - 1``, for the equal-count classes and the C0
stitching of patch networks."""

from __future__ import annotations


class DisjointSets:
    """Union-find with path halving; ``union(a, b)`` hangs ``a``'s root under ``b``'s."""

    def __init__(self, n: int):
        self.parent = list(range(int(n)))

    def find(self, x: int) -> int:
        parent = self.parent
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[ra] = rb

    def labels(self) -> list[int]:
        """Set label of every element, sets numbered in order of first appearance."""
        index: dict[int, int] = {}
        return [index.setdefault(self.find(x), len(index)) for x in range(len(self.parent))]
