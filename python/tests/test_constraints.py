"""deform_by_constraints(): point ids and targets, as Open3D's deform_as_rigid_as_possible is
called. The manipulated handle's motion is checked against a rigid fit computed here (numpy's
SVD, written independently of the package's)."""

import numpy as np
import pytest

import hgdeform

from conftest import same_bits, tube, tube_mesh


def rotation(v):
    """Rodrigues: the rotation by |v| radians about v."""
    v = np.asarray(v, dtype=np.float64)
    th = np.linalg.norm(v)
    k = v / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * kx @ kx


def kabsch(p, q):
    """R, t minimising sum |R p + t - q|^2 (no scale, det R = +1)."""
    pm, qm = p.mean(0), q.mean(0)
    u, _, vt = np.linalg.svd((p - pm).T @ (q - qm))
    d = np.diag([1.0, 1.0, np.linalg.det(vt.T @ u.T)])
    r = vt.T @ d @ u.T
    return r, qm - r @ pm


def tube_handles(n=3000, seed=71):
    points, normals = tube(n=n, seed=seed)
    base = np.flatnonzero(points[:, 0] < 1.0)
    tip = np.flatnonzero(points[:, 0] > 8.5)
    return points, normals, base, tip


@pytest.mark.parametrize("rotvec", [(0.2, -0.3, 0.5), (0.0, 0.0, 1e-7), (0.0, np.pi - 1e-9, 0.0),
                                    (1.0, 1.0, 1.0)])
def test_a_rigid_motion_of_the_targets_is_met(rotvec):
    points, _, base, tip = tube_handles()
    r, t = rotation(rotvec), np.array([0.4, 1.5, -0.8])
    ids = np.concatenate([base, tip])
    targets = np.concatenate([points[base], points[tip] @ r.T + t])
    out, report = hgdeform.deform_by_constraints(points, ids, targets, return_report=True)
    assert out.shape == points.shape and out.dtype == np.float64
    scale = np.abs(points).max()
    assert np.abs(out[tip] - (points[tip] @ r.T + t)).max() <= 1e-9 * scale
    assert same_bits(out[base], points[base])  # fixed: the targets equal the rest positions
    assert report["points"] == len(points)
    middle = np.flatnonzero((points[:, 0] > 3) & (points[:, 0] < 6))
    assert np.abs(out[middle] - points[middle]).max() > 1e-3  # the rest follows


def test_targets_that_are_not_rigid_give_the_least_squares_rigid_fit():
    points, _, base, tip = tube_handles(seed=72)
    rng = np.random.default_rng(9)
    targets = points[tip] @ rotation((0.1, 0.4, -0.2)).T + (0.3, 0.9, 0.1)
    targets += rng.normal(0, 0.05, targets.shape)  # not a rigid motion
    r, t = kabsch(points[tip], targets)
    out = hgdeform.deform_by_constraints(points, tip, targets, fixed_ids=base)
    expected = points[tip] @ r.T + t
    assert np.abs(out[tip] - expected).max() <= 1e-9 * np.abs(points).max()
    assert np.abs(out[tip] - targets).max() > 1e-3  # not the targets themselves
    assert same_bits(out[base], points[base])


def test_the_same_as_deform_with_the_fitted_frame_move():
    points, normals, base, tip = tube_handles(seed=73)
    r, t = rotation((0.0, 0.3, 0.0)), np.array([0.0, 1.0, 0.0])
    out, out_normals, report = hgdeform.deform_by_constraints(
        points, tip, points[tip] @ r.T + t, fixed_ids=base, normals=normals, clusters=6,
        return_report=True)
    assert out_normals.shape == normals.shape
    # normals turn with the tip: the tip's are rotated by r
    assert np.abs(out_normals[tip] - normals[tip] @ r.T).max() < 1e-6
    only = hgdeform.deform_by_constraints(points, tip, points[tip] @ r.T + t, fixed_ids=base,
                                          clusters=6)
    assert isinstance(only, np.ndarray) and same_bits(only, out)


def test_a_shape_comes_back_as_a_shape():
    points, _, base, tip = tube_handles(n=1500, seed=74)
    shape = hgdeform.Shape(points, fields={"label": np.arange(len(points), dtype=np.int32)})
    t = np.array([0.0, 0.0, 1.0])
    out = hgdeform.deform_by_constraints(shape, tip, points[tip] + t, fixed_ids=base)
    assert isinstance(out, hgdeform.Shape)
    assert np.abs(out.points[tip] - (points[tip] + t)).max() <= 1e-9 * 10
    assert np.array_equal(out.field("label"), np.arange(len(points)))


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(constraint_ids=[5], constraint_pos=[[0, 0, 0]]), ValueError, "no fixed point"),
    (dict(constraint_ids=[0, 1], constraint_pos=[[0, 0, 0]]), ValueError, "K×3"),
    (dict(constraint_ids=[5000], constraint_pos=[[0, 0, 0]]), ValueError, "out of range"),
    (dict(constraint_ids=[1.5], constraint_pos=[[0, 0, 0]]), TypeError, "integer"),
    (dict(constraint_ids=[3, 3], constraint_pos=[[0, 0, 0], [1, 0, 0]]), ValueError,
     "two different targets"),
    (dict(constraint_ids=[3], constraint_pos=[[0, 0, 0]], fixed_ids=[3]), ValueError,
     "fixed and given a target"),
])
def test_bad_constraints_are_refused(kwargs, error, message):
    points, _, _, _ = tube_handles(n=1000, seed=75)
    with pytest.raises(error, match=message):
        hgdeform.deform_by_constraints(points, **kwargs)


def test_nothing_to_move_is_refused():
    points, _, base, _ = tube_handles(n=1000, seed=75)
    with pytest.raises(ValueError, match="no constraint moves"):
        hgdeform.deform_by_constraints(points, base, points[base])


def test_a_mesh_with_open3d_style_arguments():
    o3d = pytest.importorskip("open3d", reason="Open3D is not installed")
    vertices, faces = tube_mesh()
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices),
                                     o3d.utility.Vector3iVector(faces.astype(np.int32)))
    base = np.flatnonzero(vertices[:, 0] < 0.5)
    tip = np.flatnonzero(vertices[:, 0] > 9.5)
    r, t = rotation((0.0, 0.0, 0.4)), np.array([0.0, 0.5, 0.0])
    ids = o3d.utility.IntVector(np.concatenate([base, tip]).tolist())
    pos = o3d.utility.Vector3dVector(np.concatenate([vertices[base], vertices[tip] @ r.T + t]))
    out = hgdeform.deform_by_constraints(mesh, ids, pos)
    assert isinstance(out, o3d.geometry.TriangleMesh) and out is not mesh
    v = np.asarray(out.vertices)
    assert np.abs(v[tip] - (vertices[tip] @ r.T + t)).max() <= 1e-9 * 10
    assert same_bits(v[base], vertices[base])
    assert np.array_equal(np.asarray(out.triangles), faces)
    # a tensor mesh with float32 positions: back as one, in float32
    tmesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(vertices.astype(np.float32)),
                                        o3d.core.Tensor(faces))
    rest32 = vertices.astype(np.float32).astype(np.float64)
    tout = hgdeform.deform_by_constraints(
        tmesh, np.concatenate([base, tip]),
        np.concatenate([rest32[base], rest32[tip] @ r.T + t]))
    assert type(tout) is o3d.t.geometry.TriangleMesh
    assert tout.vertex.positions.dtype == o3d.core.float32
    got = tout.vertex.positions.numpy().astype(np.float64)
    assert np.abs(got[tip] - (rest32[tip] @ r.T + t)).max() <= 1e-6 * 10  # float32 storage
