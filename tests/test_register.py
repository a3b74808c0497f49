"""The registration's batched least-squares step: the solutions numpy's solver gives, one system at a time."""

import numpy as np
import pytest

from pmwm.register import _lstsq


def _reference(J, r):
    return np.stack([np.linalg.lstsq(J[b], r[b], rcond=None)[0] for b in range(len(J))])


def test_lstsq_matches_numpy_on_badly_scaled_systems():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 200, 7))
    J[..., 1:4] *= 1e4  # rotation columns scale with the mesh's size, translation columns do not
    r = rng.normal(size=(6, 200))
    got, want = _lstsq(J, r), _reference(J, r)
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())


def test_lstsq_gives_no_step_along_unconstrained_directions():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(3, 100, 7))
    J[0, :, 6] = 0.0  # a motion the data do not see
    J[1, :, 5] = J[1, :, 4]  # two motions the data cannot tell apart
    J[2] = 0.0  # nothing at all
    r = rng.normal(size=(3, 100))
    got, want = _lstsq(J, r), _reference(J, r)  # numpy's: the minimum-norm solution
    assert np.all(np.isfinite(got))
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12)


@pytest.mark.slow
def test_abandoning_hopeless_finalists_keeps_the_registration(monkeypatch):
    """Half the bunny cut off and the rest moved: the cut starts win, the plain start (a wrong pose,
    sliding slowly) is abandoned early; the pose found is the one found without abandoning any."""
    from scipy.spatial import cKDTree

    from meshes import bunny
    from pmwm import attacks, register as reg

    V, F = bunny()
    frame = reg.surface_frame(V, F, 3000, seed=7)
    tree = cKDTree(V)
    for seed in (2, 3):
        W, G = attacks.similarity(*attacks.crop_plane(V, F, 0.5, seed=seed), seed=seed)
        X, info = reg.register(W, G, frame)
        assert np.median(tree.query(X)[0]) < 0.005 * frame.scale  # back on the original surface
        with monkeypatch.context() as m:
            m.setattr(reg, "ABANDON_RATIO", np.inf)
            _, full = reg.register(W, G, frame)
        assert np.allclose(info.rotation, full.rotation, atol=1e-6)
        assert np.isclose(info.scale, full.scale, rtol=1e-6) and np.isclose(info.residual, full.residual)


def test_a_mirrored_copy_registers_as_a_mirror_image():
    """The bunny mirrored, rotated, scaled and moved: one of the poses proposed is a mirror image that puts
    it back on the reference surface (rotations alone cannot)."""
    from scipy.spatial import cKDTree

    from meshes import bunny
    from pmwm import attacks, register as reg

    V, F = bunny()
    frame = reg.surface_frame(V, F, 3000, seed=7)
    tree = cKDTree(V)
    W = V * [1.0, -1.0, 1.0]
    W, G = attacks.similarity(W, F[:, ::-1], seed=4)
    poses = list(reg.register_poses(W, G, frame))
    X, info = min(poses, key=lambda x: x[1].residual)
    assert info.mirrored and np.linalg.det(info.rotation) < 0
    assert np.median(tree.query(X)[0]) < 0.005 * frame.scale
    assert len(poses) <= reg.POSES


def test_a_symmetric_shape_gets_every_symmetric_pose():
    """An ellipsoid moved at random: the surface fits equally in its 8 symmetric poses (4 rotations, 4
    mirror images); all 8 are proposed, for the mark to choose."""
    import trimesh

    from pmwm import attacks, register as reg

    sphere = trimesh.creation.icosphere(4)
    V, F = np.asarray(sphere.vertices) * [1.0, 0.7, 0.45], np.asarray(sphere.faces, np.int64)
    frame = reg.surface_frame(V, F, 3000, seed=1)
    W, G = attacks.similarity(V, F, seed=2)
    poses = list(reg.register_poses(W, G, frame))
    assert len(poses) == 8
    assert sum(info.mirrored for _, info in poses) == 4
