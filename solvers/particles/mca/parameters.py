"""The MCA solver's parameters and the choices they name, declared apart from the solver so that the
command line checks them without importing numba or scipy."""

from __future__ import annotations

from pcverify.scene import Param

COEFFICIENTS = ("hooke", "psakhie-2G/K")
PACKINGS = ("nodes", "cells")

PARAMETERS: tuple[Param, ...] = (
    Param("many_body", True, "", "many-body (volume) term on; off = pair-only (sig = E eps)", kind=bool),
    Param("coefficient", "hooke", "", "many-body coefficient: hooke = 1 - 2G/(3K), psakhie-2G/K = 1 - 2G/K",
          choices=COEFFICIENTS, kind=str),
    Param("rotations", True, "", "automata rotate (moments of the tangential forces); false holds them unturned, "
          "so a rigid turn of the body is shear to the pair law (about 2G per radian: 0.92 GPa after 1 degree, "
          "measured): small rotations only", kind=bool),
    Param("krot", 0.01, "", "rotational pair spring k_r = krot G S r0 on phi_j - phi_i (removes the zero-energy "
          "rotation modes; 0 = none)", low=0.0, high=10.0),
    Param("friction", 0.3, "", "Coulomb friction coefficient of unlinked pairs", low=0.0, high=5.0),
    Param("relink_stress", None, "Pa", "unlinked pairs re-link (micro-welding) at this compressive stress",
          low=0.0, high=1e12, low_open=True, optional=True),
    Param("cfl", 0.5, "", "time step as a fraction of 2/omega_max (Gershgorin bound; > 1 may be unstable, "
          "which is detected and reported)", low=0.0, high=10.0, low_open=True),
    Param("blowup", 100.0, "", "kinetic energy limit in units of the elastic energy of the loading (sigma_c or "
          "the support strain); above it the run stops as unstable", low=1.0, high=1e12),
    Param("damping", None, "1/s", "viscous damping rate (default: relaxation_rate for static scenes, 0 for fracture)",
          low=0.0, high=1e9, optional=True),
    Param("relax_tol", 1e-9, "", "static scenes: residual force tolerance in units of E |strain| a^2", low=0.0,
          high=1e-2, low_open=True),
    Param("ramp_periods", 2.0, "", "static scenes: load ramp length in periods of 2 pi / damping", low=0.0,
          high=1e3, low_open=True),
    Param("max_steps", 5_000_000, "", "largest number of time steps of a run", low=1, high=1e9, kind=int),
    Param("heat_cfl", 0.9, "", "heat: explicit step as a fraction of the Gershgorin-stable step", low=0.0,
          high=1.0, low_open=True),
    Param("records", 2000, "", "fracture and sliding: history rows kept", low=10, high=1e6, kind=int),
    Param("mu0", 0.0, "Pa s/m", "contact friction, viscous part: tau = mu0 |V_t| + ...", low=0.0, high=1e12),
    Param("mu1", 0.3, "", "contact friction, dry part: mu1 (1 + K_mu) min(sigma_N, sigma0) (Coulomb)", low=0.0,
          high=5.0),
    Param("sigma0", None, "Pa", "contact friction: cap of the normal stress that counts (elastic limit; none = no "
          "cap)", low=0.0, high=1e12, low_open=True, optional=True),
    Param("v_reg", 0.05, "m/s", "contact friction: below this tangential speed the dry part is regularised "
          "linearly (no static friction)", low=0.0, high=1e3, low_open=True),
    Param("friction_law", "regularised", "", "contact friction, dry law: regularised (viscous below v_reg, no "
          "static friction) or static (a tangential spring per contact with a Coulomb limit: mu_s while stuck, "
          "mu1 while slipping)", choices=("regularised", "static"), kind=str),
    Param("mu_s", None, "", "contact friction, static law: static coefficient (none = mu1; at least mu1)", low=0.0,
          high=5.0, optional=True),
    Param("contact_stiffness", None, "Pa/m", "contact friction, static law: tangential stiffness of the contact "
          "per unit area (default the bonded pair's shear stiffness 2G/h0)", low=0.0, high=1e18, low_open=True,
          optional=True),
    Param("roughness_a1", 0.0, "", "micro-roughness K_mu, sinusoid 1: mean amplitude A1/A (0 = no roughness)",
          low=0.0, high=10.0),
    Param("roughness_a2", 0.0, "", "micro-roughness K_mu, sinusoid 2: mean amplitude A2/A", low=0.0, high=10.0),
    Param("roughness_d1", 2e-4, "m", "micro-roughness, sinusoid 1: regularity d1, the mean half-period", low=0.0,
          high=1.0, low_open=True),
    Param("roughness_d2", 5e-5, "m", "micro-roughness, sinusoid 2: regularity d2, the mean half-period", low=0.0,
          high=1.0, low_open=True),
    Param("roughness_spread", 0.5, "", "micro-roughness: half-periods and amplitudes drawn uniformly within "
          "(1 +- spread) times their means", low=0.0, high=0.9),
    Param("seed", 0, "", "micro-roughness: seed of the counter-based generator", low=0, high=2**62, kind=int),
    Param("slide_ramp", None, "s", "sliding: time over which the drive speed rises smoothly (default: 2 periods "
          "2 pi / relaxation rate)", low=0.0, high=1e3, low_open=True, optional=True),
    Param("preload_tol", 1e-7, "", "sliding: residual force tolerance of the preload in units of normal_stress a^2 "
          "(measured: 1e-9 costs the frictional-heating preload 108 000 steps instead of 2 500 and changes no "
          "result beyond 1e-9)", low=0.0, high=1e-2, low_open=True),
    Param("packing", "nodes", "", "automata of the bar: nodes = one on each lattice node, centres on the faces "
          "(half, quarter, eighth cells there; n nodes across the width, a = W/(n - 1)); cells = equal cubes "
          "filling the body, centres a/2 inside the faces (n automata across the width, a = W/n; static "
          "elasticity and modes only)", choices=PACKINGS, kind=str),
    Param("slide_damping", None, "1/s", "sliding: viscous damping rate of the automata's motion relative to their "
          "body's drive (default: the relaxation rate; 0 = undamped)", low=0.0, high=1e9, optional=True),
)
