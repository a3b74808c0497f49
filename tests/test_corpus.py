"""The generated shapes of held-out benchmarks (pmwm_bench.corpus) and the data split (pmwm_bench.split).

A benchmark on generated shapes means something only if every shape is a mesh a user could hand to
pmwm (manifold, consistently oriented, no degenerate face, one piece), of the family it claims, and if
a seed names one shape: the same seed gives the same arrays, another seed another shape.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from pmwm.metrics import point_surface_distance
from pmwm_bench import corpus, split
from pmwm_bench.models import CATALOGUE

SMALL = 2500  # vertices aimed at in the per-family tests (the shapes are the same, sampled coarser)


@pytest.fixture(scope="module")
def shapes():
    cache = {}

    def get(family, seed=1, vertices=SMALL):
        if (family, seed, vertices) not in cache:
            cache[family, seed, vertices] = corpus.generate(family, seed, vertices)
        return cache[family, seed, vertices]
    return get


@pytest.mark.parametrize("family", list(corpus.FAMILIES))
def test_each_family_gives_a_clean_manifold_mesh(shapes, family):
    V, F = shapes(family)
    assert V.dtype == np.float64 and V.shape[1] == 3 and F.dtype == np.int64 and F.shape[1] == 3
    r = corpus.mesh_report(V, F)
    assert r["overfull_edges"] == 0 and r["pinched_vertices"] == 0, r
    assert r["misoriented_edges"] == 0, r
    assert r["unreferenced_vertices"] == 0 and r["repeated_corner_faces"] == 0, r
    assert r["min_area_ratio"] > 1e-4, r  # no face shrunk to nothing
    assert r["components"] == 1, r
    mesh = trimesh.Trimesh(V, F, process=False)
    assert mesh.is_winding_consistent
    if family in corpus.CLOSED_FAMILIES:
        assert r["boundary_edges"] == 0 and mesh.is_watertight, r
        assert r["signed_volume"] > 0, r  # faces point outward
    elif family == "open":
        assert r["boundary_loops"] == 1 and r["euler"] == 1, r  # a disk
    else:  # scan: a closed surface with small holes
        assert family == "scan"
        assert r["boundary_loops"] >= 1 and r["boundary_edges"] < 0.05 * r["faces"], r


@pytest.mark.parametrize("family", list(corpus.FAMILIES))
def test_a_seed_names_one_shape(shapes, family):
    V, F = shapes(family)
    V2, F2 = corpus.generate(family, 1, SMALL)
    assert np.array_equal(V, V2) and np.array_equal(F, F2)
    V3, _ = shapes(family, seed=2)
    assert V3.shape != V.shape or not np.allclose(V3, V)


def test_default_sizes_span_a_few_thousand_to_thirty_thousand_vertices():
    sizes = [len(corpus.generate(family, 3)[0]) for family in ("ellipsoid", "open", "cad")]
    assert all(2000 <= n <= 32000 for n in sizes), sizes


def test_near_symmetric_ellipsoid_is_nearly_its_own_mirror_image(shapes):
    """The ellipsoid's principal axes of inertia are its mirror planes but for one small bump: reflected
    across each, most vertices stay within 0.2 % of its size of its surface, and the bump does not."""
    V, F = shapes("ellipsoid")
    mesh = trimesh.Trimesh(V, F, process=False)
    C = V - mesh.center_mass
    size = np.linalg.norm(C.max(0) - C.min(0))
    for a in mesh.principal_inertia_vectors:
        d = point_surface_distance(C - 2 * np.outer(C @ a, a), C, F)
        assert np.quantile(d, 0.9) < 0.002 * size and d.max() > 0.002 * size


def test_unknown_family_is_refused():
    with pytest.raises(ValueError, match="unknown family"):
        corpus.generate("teapot", 0)


def test_split_keeps_tuning_and_report_meshes_apart():
    assert not set(split.TUNING) & set(split.REPORT_ONLY)
    catalogue_files = {m.file for m in CATALOGUE.values()}
    assert catalogue_files <= set(split.TUNING) | set(split.REPORT_ONLY)
    assert set(split.SAME_SUBJECT) <= set(split.REPORT_ONLY)
    assert set(split.SAME_SUBJECT.values()) <= set(split.TUNING)


def test_fresh_seeds_are_recorded_and_read_back(tmp_path):
    record = tmp_path / "seeds.json"
    seeds = split.draw_corpus(3, ["organic", "cad"], record=record)
    assert split.read_seeds(record) == seeds
    assert len({s for v in seeds.values() for s in v}) == 6  # 63-bit draws: no repeat
    with pytest.raises(FileExistsError):  # a record is never overwritten
        split.draw_corpus(1, record=record)
    with pytest.raises(ValueError, match="unknown families"):
        split.draw_corpus(1, ["teapot"])
