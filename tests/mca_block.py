"""Uniaxial-stress block test of the MCA automata: the loading-unloading curve sigma(eps) of a block.

A box of automata (default 3 x 3 x 3, 10 mm cube) stands on frictionless supports on face z0 (plus the
force-free "3-2-1" set against rigid motion); face zL is moved along z through a strain path, lateral faces
are free.  Each increment is applied as a ramp over `ramp_periods` periods 2 pi / gamma and relaxed with
viscous damping gamma (2 Model.relaxation_rate) until the largest free residual force is below
tol * E eps_scale h^2: a quasi-static loading.  The stress is the reaction on zL over the face area.  With
the automata's exact geometric identities (automata.py) a homogeneous block is in a uniaxial stress state,
so the curve must be the response function's own sigma = f(eps) (response.uniaxial_curve).
"""

from __future__ import annotations

import math

import numpy as np

from pcverify.scene import Response
from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca.automata import build_automata
from pcverify.solvers.particles.mca.model import Elastic, Model, relax


def block_curve(resp: Response | None, youngs: float, poisson: float, strain_path: np.ndarray,
                shape: tuple[int, int, int] = (3, 3, 3), extent: float = 0.01, density: float = 2800.0,
                many_body: bool = True, coefficient: str = "hooke", fracture: bool = True, tol: float = 1e-7,
                ramp_periods: float = 2.0, relink_stress: float | None = None) -> dict[str, np.ndarray]:
    """Measured (strain, stress, lateral strain, linked fraction) after relaxing at each point of the path."""
    ext = np.full(3, float(extent))
    aut = build_automata(ext, shape, density)
    el = Elastic(youngs, poisson, many_body=many_body, coefficient=coefficient)
    n = aut.size
    fixm = np.zeros((n, 6), dtype=np.uint8)
    fixv = np.zeros((n, 6))
    group = np.zeros(n, dtype=np.int64)
    z0 = aut.on_face("z0", ext)
    zl = aut.on_face("zL", ext)
    fixm[z0, 2] = fixm[zl, 2] = 1
    corner = z0[np.argmin(np.linalg.norm(aut.positions[z0, :2], axis=1))]
    side = z0[np.argmin(np.linalg.norm(aut.positions[z0, :2] - [extent, 0.0], axis=1))]
    fixm[corner, 0] = fixm[corner, 1] = fixm[side, 1] = 1
    group[zl] = 1
    probe = Model(aut, el)
    gamma = 2.0 * probe.relaxation_rate()  # near critical for the block's slowest mode (the block is short)
    t_inc = ramp_periods * 2 * math.pi / gamma
    model = Model(aut, el, response=resp, fracture=fracture, fixm=fixm, fixv=fixv, group=group, gamma=gamma,
                  t_stop=0.0, relink_stress=relink_stress)
    st = model.new_state()
    h = float(aut.spacing.min())
    path = np.asarray(strain_path, dtype=float)
    scale = youngs * max(float(np.abs(path).max()), 1e-12) * h * h
    area = extent * extent
    out = {k: np.full(len(path), np.nan) for k in ("strain", "stress", "lateral", "linked", "residual")}
    current = 0.0
    xw = aut.on_face("xW", ext)
    x0 = aut.on_face("x0", ext)
    for k, target in enumerate(path):
        du = (target - current) * extent
        model.fixv[zl, 2] = du / t_inc
        model.params = model.params._replace(t_stop=float(st.clock[0]) + t_inc)
        status, res, _ = relax(model, st, scale, tol=tol, chunk=200)
        if status != mk.OK:
            break
        current = target
        u = st.x - aut.positions
        out["strain"][k] = float(u[zl, 2].mean() / extent)
        out["stress"][k] = float(-st.f[zl, 2].sum() / area)
        out["lateral"][k] = float((u[xw, 0].mean() - u[x0, 0].mean()) / extent)
        out["linked"][k] = float(st.linked.mean())
        out["residual"][k] = res
    out["steps"] = np.array(int(st.counters[mk.C_STEPS]))
    out["pair_steps"] = np.array(int(st.counters[mk.C_PAIRSTEPS]))
    return out
