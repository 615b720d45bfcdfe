"""Segment closest points and the KD-tree contact search with periodic images and self-contact."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe.numerics.contact_search import SegmentTopology, closest_points, find_pairs
from knitframe.numerics.periodic import Lattice, macro_index


def brute(p0, p1, q0, q1, n=201):
    s, t = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    c = p0 + s.reshape(-1, 1) * (p1 - p0) - q0 - t.reshape(-1, 1) * (q1 - q0)
    return np.linalg.norm(c, axis=1).min()


def dist(p0, p1, q0, q1):
    s, t = closest_points(p0, p1, q0, q1)
    return np.linalg.norm(p0 + s[:, None] * (p1 - p0) - q0 - t[:, None] * (q1 - q0), axis=1)


def test_closest_points_match_brute_force():
    """Vectorised closest distances equal a dense grid search, crossing or clamped."""
    rng = np.random.default_rng(7)
    P = rng.standard_normal((40, 4, 3))
    d = dist(P[:, 0], P[:, 1], P[:, 2], P[:, 3])
    ref = np.array([brute(*p) for p in P])
    assert np.all(d <= ref + 1e-12) and np.allclose(d, ref, atol=2e-2)


def test_parallel_and_degenerate_segments():
    """Parallel segments and zero-length segments give exact distances, not NaN."""
    p0 = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 0]])
    p1 = np.array([[1.0, 0, 0], [0, 0, 0], [1, 0, 0]])
    q0 = np.array([[0.5, 0.3, 0], [0.2, 0.1, 0], [3, 0.4, 0]])
    q1 = np.array([[2.0, 0.3, 0], [0.2, 0.1, 0], [4, 0.4, 0]])
    assert np.allclose(dist(p0, p1, q0, q1), [0.3, np.hypot(0.2, 0.1), np.hypot(2.0, 0.4)])


def _topology(n_seg, strand, arc, cycle=(0,), length=(0.0,)):
    return SegmentTopology(
        np.asarray(strand),
        np.zeros(n_seg, np.int64),
        np.asarray(arc, float),
        np.asarray(cycle),
        np.asarray(length, float),
    )


def test_self_contact_needs_the_effect_and_skips_neighbours():
    """A hairpin's legs touch only with self-contact on; adjacent segments are never contacts."""
    s = np.linspace(0, np.pi, 30)
    leg = np.linspace(0, 3, 10)
    pts = np.vstack(
        [
            np.stack([leg[::-1], np.full(10, 0.2), np.zeros(10)], 1)[:-1],
            np.stack([-0.2 * np.sin(s), 0.2 * np.cos(s), np.zeros(30)], 1)[:-1],
            np.stack([leg, np.full(10, -0.2), np.zeros(10)], 1),
        ]
    )
    p0, p1 = pts[:-1], pts[1:]
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(p1 - p0, axis=1))])[:-1] + 0.5 * np.linalg.norm(
        p1 - p0, axis=1
    )
    topo = _topology(len(p0), np.zeros(len(p0), np.int64), arc)
    off = find_pairs(p0, p1, 0.45, topology=topo)
    on = find_pairs(p0, p1, 0.45, topology=topo, self_contact=True, exclusion=np.pi * 0.45)
    assert len(off) == 0
    assert len(on) > 0 and np.allclose(on.distance.min(), 0.4, atol=1e-9)
    assert np.all(np.abs(arc[on.i] - arc[on.j]) >= np.pi * 0.45)


def test_images_follow_the_macro_stretch():
    """A straight periodic yarn touches its wale image; stretching the wale separates them."""
    lat = Lattice([1.0, 0, 0], [0, 0.5, 0])
    x = np.linspace(0, 1, 5)[:-1]
    p0 = np.stack([x, np.zeros(4), np.zeros(4)], 1)
    p1 = p0 + [0.25, 0, 0]
    topo = SegmentTopology(
        np.zeros(4, np.int64), np.zeros(4, np.int64), x + 0.125, np.array([1]), np.array([1.0])
    )
    h = np.zeros(6)
    close = find_pairs(p0, p1, 0.6, topology=topo, lattice=lat, h=h)
    assert len(close) > 0 and np.all(close.k[:, 1] != 0) and close.distance.min() == pytest.approx(0.5)
    h[macro_index(1, 1)] = 0.3  # wale stretch 1.3: images 0.65 apart
    assert len(find_pairs(p0, p1, 0.6, topology=topo, lattice=lat, h=h)) == 0
    # along the course the yarn continues into its own image: those are neighbours, not contacts
    assert not np.any(close.k[:, 1] == 0)


def test_pairs_are_not_double_counted():
    """Each pair appears once, not also as its twin (j, i, −k)."""
    lat = Lattice([1.0, 0, 0], [0, 0.5, 0])
    x = np.linspace(0, 1, 5)[:-1]
    p0 = np.stack([x, np.zeros(4), np.zeros(4)], 1)
    topo = SegmentTopology(
        np.zeros(4, np.int64), np.zeros(4, np.int64), x + 0.125, np.array([1]), np.array([1.0])
    )
    pr = find_pairs(p0, p0 + [0.25, 0, 0], 0.51, topology=topo, lattice=lat, h=np.zeros(6))
    keys = {(a, b, tuple(k)) for a, b, k in zip(pr.i, pr.j, pr.k)}
    twins = {(b, a, (-k[0], -k[1])) for a, b, k in keys}
    assert len(keys) == len(pr) and not (keys & twins)


def test_a_verlet_list_gives_the_pairs_of_a_fresh_search():
    """Along a path of small random moves and a growing macro stretch, the search that keeps its broad-phase
    candidates (a Verlet list) returns exactly the pairs, parameters and distances of a fresh search, reusing
    its list most of the time and rebuilding it when something moved far."""
    from knitframe.numerics.contact_search import VerletList

    rng = np.random.default_rng(3)
    lat = Lattice([4.0, 0, 0], [0, 3.0, 0])
    n = 60
    p0 = rng.uniform([0, 0, -0.3], [4.0, 3.0, 0.3], (n, 3))
    d = rng.standard_normal((n, 3))
    p1 = p0 + 0.4 * d / np.linalg.norm(d, axis=1)[:, None]
    topo = SegmentTopology(
        np.arange(n), np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.int64), np.ones(n)
    )
    verlet = VerletList()
    h = np.zeros(6)
    for step in range(40):
        move = 0.01 * rng.standard_normal((n, 3)) if step != 25 else 0.5 * rng.standard_normal((n, 3))
        p0, p1 = p0 + move, p1 + move
        h[macro_index(0, 0)] += 0.002
        fresh = find_pairs(p0, p1, 0.5, topology=topo, lattice=lat, h=h)
        kept = find_pairs(p0, p1, 0.5, topology=topo, lattice=lat, h=h, verlet=verlet)
        assert len(fresh) > 10
        for a in ("i", "j", "k", "s", "t", "distance"):
            np.testing.assert_array_equal(getattr(kept, a), getattr(fresh, a))
    assert verlet.uses > 20 and 2 <= verlet.builds < 15
