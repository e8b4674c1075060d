"""Large-rotation statics and a short swing with the structural core.

1. Sze et al. (2004) case 3.1: a strip clamped at one end, tip shear up to P = 4, 16x1 mesh.
2. The paper's packaging sheet (coarse mesh) swinging under gravity for 0.2 s.

Run: python examples/shell_cantilever.py
"""

import numpy as np

import flexparcel as fp


def cantilever_end_shear() -> float:
    points, quads = fp.mesh.rectangle(10.0, 1.0, 16, 1)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    mat = fp.ShellMaterial(youngs_modulus=1.2e6, poisson_ratio=0.0, density=1.0, thickness=0.1)
    ids = b.add_shell_mesh(points, quads, material=mat)
    b.clamp(ids[points[:, 0] == 0.0])
    tip = ids[np.isclose(points[:, 0], 10.0)]
    b.add_force(tip, (0.0, 0.0, 4.0 / len(tip)))
    res = fp.solve_static(b.finalize(), load_steps=10)
    w = res.displacements[-1, tip, 2].mean()
    print(f"Sze 3.1 tip deflection at P = 4: {w:.4f} (reference 6.698)")
    return w


def sheet_swing() -> float:
    length, width, t = 0.275, 0.2, 0.3e-3
    points, quads = fp.mesh.rectangle(length, width, 11, 8)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    mat = fp.ShellMaterial(
        youngs_modulus=926e6,
        poisson_ratio=0.1,
        density=0.040 / (length * width * t),
        thickness=t,
        damping_ratio=1.71e-3,
    )
    ids = b.add_shell_mesh(points, quads, material=mat)
    b.clamp(ids[points[:, 0] <= 0.02 + 1e-9])
    tip = ids[np.isclose(points[:, 0], length)]
    res = fp.simulate(b.finalize(), t_end=0.2, dt_out=0.01)
    drop = res.positions[-1, tip, 2].mean()
    print(
        f"sheet free end after 0.2 s: z = {1e3 * drop:.1f} mm, "
        f"{res.stats['steps']} steps, {res.stats['newton_iterations']} Newton iterations"
    )
    return drop


if __name__ == "__main__":
    cantilever_end_shear()
    sheet_swing()
