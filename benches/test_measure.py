#!/usr/bin/env python3
"""Unit tests of benches/measure.py and benches/primitive_mesh.py, run by hand (not in CI):

    python benches/test_measure.py
"""
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from measure import Model, closest_points_on_triangles, measure, sample_surface, triangle_areas  # noqa: E402
from primitive_mesh import cylinder_cells, cylinder_tube, merge, plane_cells  # noqa: E402


def unit_square(z=0.0, side=1.0):
    """Two triangles covering [0, side]² at height z."""
    v = np.array([[0, 0, z], [side, 0, z], [side, side, z], [0, side, z]], float)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def grid_points(z=0.0, n=50, side=1.0):
    """An n × n grid of points on [0, side]² at height z (cell centres)."""
    t = (np.arange(n) + 0.5) / n * side
    x, y = np.meshgrid(t, t)
    return np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])


class ClosestPoint(unittest.TestCase):
    def test_regions_against_brute_force(self):
        rng = np.random.default_rng(1)
        a, b, c = (np.tile(v, (2000, 1)) for v in ([0, 0, 0], [2, 0, 0], [0.5, 1.5, 0.2]))
        p = rng.uniform(-2, 3, (2000, 3))
        got = np.linalg.norm(p - closest_points_on_triangles(p, a, b, c), axis=1)
        s, t = np.meshgrid(np.linspace(0, 1, 401), np.linspace(0, 1, 401))
        keep = (s + t) <= 1
        dense = a[0] + np.outer(s[keep], b[0] - a[0]) + np.outer(t[keep], c[0] - a[0])
        from scipy.spatial import cKDTree

        brute, _ = cKDTree(dense).query(p)
        self.assertTrue(np.all(got <= brute + 1e-12))
        self.assertLess(np.max(brute - got), 0.01)


class Sampling(unittest.TestCase):
    def test_area_uniform_count(self):
        v, f = unit_square(side=2.0)
        points, face = sample_surface(v, f, 0.01)
        self.assertAlmostEqual(len(points) / 40_000, 1.0, delta=0.01)
        self.assertAlmostEqual(np.mean(face == 0), 0.5, delta=0.01)
        self.assertTrue(np.all((points[:, :2] >= 0) & (points[:, :2] <= 2)))


class Measures(unittest.TestCase):
    def test_offset_plane(self):
        """Points 1 cm above a square that they cover: point→model 1 cm, full coverage, no overlap."""
        v, f = unit_square()
        model = Model(v, f, np.zeros(2, int), ["plane"])
        m = measure(grid_points(z=0.01), model, spacing=0.02)
        self.assertAlmostEqual(m["point_to_model_mean"], 0.01, places=6)
        self.assertAlmostEqual(m["coverage"], 1.0)
        self.assertEqual(m["overlap_share"], 0.0)
        self.assertLess(m["model_to_point_mean"], 0.02)  # ≈ √(0.01² + in-plane ~0.006²)
        self.assertEqual(m["by_type"], {"plane": 1})

    def test_double_cover_is_full_overlap(self):
        """Two primitives on the same square: all model area overlaps."""
        v, f = unit_square()
        v2, f2 = unit_square(z=0.001)
        model = Model(np.vstack([v, v2]), np.vstack([f, f2 + 4]), np.array([0, 0, 1, 1]), ["plane", "plane"])
        m = measure(grid_points(), model, spacing=0.02)
        self.assertEqual(m["overlap_share"], 1.0)
        self.assertAlmostEqual(m["area"], 2.0)

    def test_corner_band_counts(self):
        """Floor and wall meeting at an edge: the band of h next to it counts as overlap."""
        v, f = unit_square()
        wall = v[:, [0, 2, 1]]  # the square turned into the plane y = 0
        model = Model(np.vstack([v, wall]), np.vstack([f, f + 4]), np.array([0, 0, 1, 1]), ["plane", "plane"])
        m = measure(grid_points(), model, spacing=0.02)
        self.assertAlmostEqual(m["overlap_share"], 0.04, delta=0.005)  # h = 0.04 of each unit square


class FarSamples(unittest.TestCase):
    def test_far_mean_matches_exact(self):
        """Model→point of samples far from the points: the subset estimate is close to the exact mean."""
        import measure as m
        from scipy.spatial import cKDTree

        rng = np.random.default_rng(2)
        points = rng.uniform(0, 1, (2000, 3))
        samples = np.vstack([rng.uniform(0, 1, (1000, 3)), rng.uniform(3, 9, (50_000, 3))])
        tree = cKDTree(points)
        exact = tree.query(samples)[0].mean()
        estimate, bounded = m.mean_distance_to_points(samples, tree, reach=0.5)
        self.assertAlmostEqual(estimate, exact, delta=0.01 * exact)
        self.assertEqual(int(np.isfinite(bounded).sum()), 1000)


class BaselineMeshes(unittest.TestCase):
    def test_plane_cells_cover_inliers(self):
        pts = grid_points(n=40)
        v, f = plane_cells(pts, np.array([0, 0, 1.0]), 0.0, cell=0.1)
        self.assertAlmostEqual(triangle_areas(v, f).sum(), 1.0)

    def test_tube_area(self):
        axis = np.array([0, 0, 1.0])
        t = np.linspace(0, 2, 100)
        pts = np.column_stack([np.cos(t), np.sin(t), t]) * [0.5, 0.5, 1]
        v, f = cylinder_tube(pts, np.zeros(3), axis, 0.5, segments=256)
        self.assertAlmostEqual(triangle_areas(v, f).sum(), 2 * np.pi * 0.5 * 2, delta=0.01)

    def test_cylinder_cells_cover_half_a_tube(self):
        """Inliers on half of a cylinder: the cells cover that half (up to one cell at the ends)."""
        theta, z = np.meshgrid(np.linspace(0.01, np.pi - 0.01, 200), np.linspace(0.0, 1.0, 50))
        pts = np.column_stack([0.5 * np.cos(theta.ravel()), 0.5 * np.sin(theta.ravel()), z.ravel()])
        v, f = cylinder_cells(pts, np.zeros(3), np.array([0, 0, 1.0]), 0.5, cell=0.05)
        self.assertAlmostEqual(triangle_areas(v, f).sum(), np.pi * 0.5 * 1.0, delta=0.15)
        self.assertTrue(np.allclose(np.hypot(v[:, 0], v[:, 1]), 0.5))

    def test_merge_ids(self):
        v, f = unit_square()
        model = merge([(v, f, "plane"), (v + 1, f, "cylinder")])
        self.assertEqual(list(model.face_primitive), [0, 0, 1, 1])
        self.assertEqual(model.primitive_types, ["plane", "cylinder"])


if __name__ == "__main__":
    unittest.main()
