"""Response functions sigma = f(eps) of the MCA automata (Fig. 3 of the MCA paper): the kernel's numbers for
the scene's `Response`, and the exact uniaxial curve the block test compares against.

Elastic, degradation (damage), plastic (radial return) and plastic-degradation, one post-linear modulus H;
fracture at the Drucker-Prager equivalent stress (docs/physics.md, "The MCA solver in detail", "Response functions").
"""

from __future__ import annotations

import math

import numpy as np

from pcverify.scene import Response, SceneError

KINDS = {"elastic": 0, "degradation": 1, "plastic": 2, "plastic-degradation": 3}


def kind_code(resp: Response | None) -> int:
    return 0 if resp is None else KINDS[resp.kind]


def damage_on(code: int) -> bool:
    return code in (1, 3)


def plastic_on(code: int) -> bool:
    return code in (2, 3)


def plastic_modulus(youngs: float, hardening: float) -> float:
    """Plastic modulus H' = E H / (E - H) that gives the uniaxial tangent H after yield."""
    if not 0.0 <= hardening < youngs:
        raise SceneError(f"hardening={hardening!r} is out of range; allowed: number in [0, E={youngs:g}) Pa")
    return youngs * hardening / (youngs - hardening)


def damage(kappa: float, youngs: float, resp: Response) -> float:
    """Damage d(kappa) of kinds (b) and (d): 0 up to sigma_d, then 1 - g(kappa)/kappa."""
    if kappa <= resp.sigma_d:
        return 0.0
    g = resp.sigma_d + resp.hardening / youngs * (kappa - resp.sigma_d)
    return 1.0 - g / kappa


def uniaxial_curve(resp: Response, youngs: float, strain: np.ndarray) -> np.ndarray:
    """Exact uniaxial stress along the strain path `strain` (start 0), NaN after fracture.

    One-dimensional return mapping for the plastic part (linear isotropic hardening), damage on the
    running maximum of the effective stress, fracture when the Drucker-Prager equivalent stress of the
    transmitted stress reaches sigma_c (tension: s = sigma_c / k, compression: |s| = sigma_c)."""
    eps = np.asarray(strain, dtype=float)
    code = kind_code(resp)
    hp = plastic_modulus(youngs, resp.hardening) if plastic_on(code) else 0.0
    out = np.empty_like(eps)
    ep = alpha = kappa = 0.0
    broken = False
    limit = tensile_strength(resp)
    for k, e in enumerate(eps):
        if broken:
            out[k] = math.nan
            continue
        s_eff = youngs * (e - ep)
        if plastic_on(code):
            f = abs(s_eff) - (resp.sigma_y + hp * alpha)
            if f > 0:
                dg = f / (youngs + hp)
                ep += math.copysign(dg, s_eff)
                alpha += dg
                s_eff = youngs * (e - ep)
        kappa = max(kappa, abs(s_eff))
        d = damage(kappa, youngs, resp) if damage_on(code) else 0.0
        s = (1.0 - d) * s_eff
        if (s > 0 and s >= limit * (1 - 1e-12)) or (s < 0 and -s >= resp.sigma_c * (1 - 1e-12)):
            broken = True
        out[k] = s
    return out


def tensile_strength(resp: Response) -> float:
    """Uniaxial tensile stress at which sigma_eq reaches sigma_c: with sigma_int = s, sigma_mean = s/3,
    sigma_eq = k s, so sigma_t = sigma_c / k (in compression sigma_eq = s: the strength is sigma_c)."""
    return resp.sigma_c / resp.k


def kernel_params(resp: Response | None, youngs: float) -> np.ndarray:
    """[sigma_c, k, sigma_y, H', sigma_d, H/E] for the kernel (inf strengths when there is no response)."""
    if resp is None:
        return np.array([math.inf, 1.0, math.inf, 0.0, math.inf, 0.0])
    code = kind_code(resp)
    hp = plastic_modulus(youngs, resp.hardening) if plastic_on(code) else 0.0
    return np.array([resp.sigma_c, resp.k, resp.sigma_y, hp, resp.sigma_d, resp.hardening / youngs])
