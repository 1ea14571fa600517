"""Disjoint sets (meshfit._unionfind), the union-find of the equal-count classes and of C0
stitching."""

from meshfit._unionfind import DisjointSets


def test_unions_and_first_appearance_labels():
    sets = DisjointSets(7)
    sets.union(5, 1)
    sets.union(1, 3)
    sets.union(6, 4)
    assert sets.find(5) == sets.find(3) == 3  # a's root hangs under b's
    assert sets.labels() == [0, 1, 2, 1, 3, 1, 3]
    sets.union(3, 5)  # already one set: nothing changes
    assert sets.labels() == [0, 1, 2, 1, 3, 1, 3]
    assert DisjointSets(0).labels() == []
