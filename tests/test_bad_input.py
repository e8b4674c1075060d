"""Bad input gives errors that name the field and the allowed range."""

import numpy as np
import pytest

import flexparcel as fp


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(youngs_modulus=-1.0), r"youngs_modulus must be > 0 Pa"),
        (dict(youngs_modulus=0.0), r"youngs_modulus must be > 0 Pa"),
        (dict(poisson_ratio=0.5), r"poisson_ratio must be in \[0, 0.5\)"),
        (dict(poisson_ratio=-0.1), r"poisson_ratio must be in \[0, 0.5\)"),
        (dict(density=0.0), r"density must be > 0 kg/m\^3"),
        (dict(thickness=-1e-3), r"thickness must be > 0 m"),
        (dict(damping_ratio=-1e-3), r"damping_ratio .* must be >= 0 s"),
        (dict(youngs_modulus=float("nan")), r"youngs_modulus must be finite"),
        (dict(thickness=float("inf")), r"thickness must be finite"),
        (dict(density="heavy"), r"density must be a number"),
    ],
)
def test_shell_material_validation(kwargs, match):
    base = dict(youngs_modulus=1e9, poisson_ratio=0.3, density=1000.0, thickness=1e-3)
    base.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fp.ShellMaterial(**base)


MAT = fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3)


def _square():
    return fp.mesh.rectangle(1.0, 1.0, 2, 2)


def test_degenerate_element():
    pts, q = _square()
    pts[4] = pts[3]  # collapse a node onto its neighbour: zero-area quads
    with pytest.raises(ValueError, match=r"quads\[\d+\] = .* is (degenerate|inverted)"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)


def test_repeated_node_in_element():
    pts, q = _square()
    q[1, 2] = q[1, 1]
    with pytest.raises(ValueError, match=r"quads\[1\] .* repeats a node"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)


def test_inverted_element():
    pts, q = _square()
    q[2] = q[2, ::-1]  # clockwise: normal opposite to its neighbours
    with pytest.raises(ValueError, match=r"inverted"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)


def test_nonconvex_quad():
    pts, q = fp.mesh.rectangle(1.0, 1.0, 1, 1)
    pts[2] = (0.3, 0.2, 0.0)  # corner pulled inside: a dart-shaped quad
    with pytest.raises(ValueError, match=r"inverted or non-convex"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)


def test_duplicate_element():
    pts, q = _square()
    q = np.vstack([q, q[0]])
    with pytest.raises(ValueError, match=r"duplicated"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)


def test_node_ids_out_of_range():
    pts, q = _square()
    q[0, 0] = 99
    with pytest.raises(ValueError, match=r"outside \[0, 8\]"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)
    b = fp.ModelBuilder()
    pts, q = _square()
    b.add_shell_mesh(pts, q, material=MAT)
    with pytest.raises(ValueError, match=r"clamp|fix: node id 9 is outside \[0, 8\]"):
        b.clamp([9])
    with pytest.raises(ValueError, match=r"add_force: node id -1 is outside"):
        b.add_force([-1], (0, 0, 1))


def test_nan_inputs():
    pts, q = _square()
    pts[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"points\[3\] is not finite"):
        fp.ModelBuilder().add_shell_mesh(pts, q, material=MAT)
    b = fp.ModelBuilder()
    pts, q = _square()
    b.add_shell_mesh(pts, q, material=MAT)
    with pytest.raises(ValueError, match=r"add_moment: vector must be 3 finite numbers"):
        b.add_moment([1], (0, np.inf, 0))
    with pytest.raises(ValueError, match=r"gravity must be 3 finite numbers"):
        fp.ModelBuilder(gravity=(0, 0, np.nan))


def test_load_on_fixed_dof_is_inconsistent():
    b = fp.ModelBuilder()
    pts, q = _square()
    ids = b.add_shell_mesh(pts, q, material=MAT)
    b.clamp(ids[:3])
    b.add_force(ids[1], (0.0, 0.0, 5.0))
    with pytest.raises(ValueError, match=r"force on node 1 acts on a fixed DOF"):
        b.finalize()
    b2 = fp.ModelBuilder()
    ids = b2.add_shell_mesh(pts, q, material=MAT)
    b2.fix(ids[:3], "rotations")
    b2.add_moment(ids[2], (1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"moment on node 2 acts on a fixed DOF"):
        b2.finalize()


def test_unknown_dof_name_and_bad_steps():
    b = fp.ModelBuilder()
    pts, q = _square()
    ids = b.add_shell_mesh(pts, q, material=MAT)
    with pytest.raises(ValueError, match=r"unknown DOF 'w'"):
        b.fix(ids[0], ["w"])
    with pytest.raises(ValueError, match=r"dofs must be one of"):
        b.fix(ids[0], "everything")
    b.clamp(ids[:3])
    model = b.finalize()
    with pytest.raises(ValueError, match=r"load_steps must be an integer >= 1"):
        fp.solve_static(model, load_steps=0)
    with pytest.raises(ValueError, match=r"t_end must be > 0 s"):
        fp.simulate(model, -1.0)
    with pytest.raises(ValueError, match=r"rho_inf must be in \[0, 1\]"):
        fp.IntegratorOptions(rho_inf=1.5)


def test_orphan_node_and_all_fixed():
    pts, q = _square()
    pts = np.vstack([pts, [[5.0, 5.0, 0.0]]])
    b = fp.ModelBuilder()
    b.add_shell_mesh(pts, q, material=MAT)
    with pytest.raises(ValueError, match=r"node 9 belongs to no element"):
        b.finalize()
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(*_square(), material=MAT)
    b.clamp(ids)
    with pytest.raises(ValueError, match=r"every DOF is fixed"):
        b.finalize()


def test_rectangle_arguments():
    with pytest.raises(ValueError, match=r"length must be > 0 m"):
        fp.mesh.rectangle(0.0, 1.0, 2, 2)
    with pytest.raises(ValueError, match=r"nx and ny must be integers >= 1"):
        fp.mesh.rectangle(1.0, 1.0, 0, 2)
