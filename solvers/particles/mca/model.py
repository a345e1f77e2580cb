"""MCA model: material constants, the automata's state and the two ways of running it.

`Model` binds automata, elastic constants and the kernel's parameters; `State` holds every array the
kernel advances.  `run` integrates in time (dynamic loading, energy history); `relax` integrates with
viscous damping until the residual force on the free degrees of freedom is below a tolerance
(dynamic relaxation: the quasi-static approach for static scenes).

Many-body coefficient (PHYSICS.md §4 gives 1 - 2G/K and 1 - 2G/(3K)).  The pair's normal stress is
    sig_ij = 2 G eps_ij + D P_i,  P_i = K theta_i (mean stress of the automaton, theta its volume strain),
eps_ij = n.eps.n the normal strain of the pair.  For a homogeneous strain eps of the lattice every automaton
has theta = tr eps (the geometric identities of mca_lattice), so sig_ij = n.(2 G eps + D K tr(eps) I).n,
which is Hooke's law n.sigma.n = n.(2 G eps + lambda tr(eps) I).n for every direction n exactly when
    D K = lambda = K - 2G/3,  i.e.  D = 1 - 2G/(3K).
The other form, D = 1 - 2G/K, gives lambda' = K - 2G and so Poisson's ratio lambda'/(2(lambda' + G))
(0.19 instead of 0.33 for duralumin); the uniaxial-stress tests (tests/test_mca.py) measure both.  The
tangential stress 2G gamma, gamma the pair's shear strain at the contact point (relative displacement of
the contact points including the automata's rotations over r0), gives the shear modulus G.
Without the many-body term (`many_body = false`) a pair carries sig = E eps_ij: a lattice of central
normal springs along the cube axes has no lateral coupling, so nu_eff = 0 (measured, not assumed).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from pcverify.scene import Response, SceneError

from . import kernel as mk
from . import response as rf
from .automata import Automata
from .stiffness import mass_diagonal, omega_max_bound, stiffness

COEFFICIENTS = ("hooke", "psakhie-2G/K")


@dataclass(frozen=True)
class Elastic:
    """Elastic constants and the pair moduli they give."""

    youngs: float
    poisson: float
    many_body: bool = True
    coefficient: str = "hooke"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.youngs) and self.youngs > 0):
            raise SceneError(f"youngs_modulus={self.youngs!r} is out of range; allowed: number in (0, inf) Pa")
        if not (math.isfinite(self.poisson) and -1.0 < self.poisson < 0.5):
            raise SceneError(f"poisson_ratio={self.poisson!r} is out of range; allowed: number in (-1, 0.5)")
        if self.coefficient not in COEFFICIENTS:
            raise SceneError(f"coefficient={self.coefficient!r} is not allowed; allowed: {', '.join(COEFFICIENTS)}")

    @property
    def shear(self) -> float:
        return self.youngs / (2 * (1 + self.poisson))

    @property
    def bulk(self) -> float:
        return self.youngs / (3 * (1 - 2 * self.poisson))

    @property
    def lam(self) -> float:
        """lam = D K, the many-body modulus (0 without the many-body term)."""
        if not self.many_body:
            return 0.0
        d = 1 - 2 * self.shear / (3 * self.bulk) if self.coefficient == "hooke" else 1 - 2 * self.shear / self.bulk
        return d * self.bulk

    @property
    def kn(self) -> float:
        """Normal pair modulus: 2G with the many-body term, E without."""
        return 2 * self.shear if self.many_body else self.youngs

    @property
    def contact(self) -> float:
        """Modulus of an unlinked pair in compression: the P-wave modulus K + 4G/3."""
        return self.bulk + 4 * self.shear / 3


@dataclass(eq=False)
class State:
    """Every array the kernel advances (see mca_kernel for the meaning)."""

    x: np.ndarray
    v: np.ndarray
    phi: np.ndarray
    w: np.ndarray
    f: np.ndarray
    mom: np.ndarray
    dx: np.ndarray
    dphi: np.ndarray
    xref: np.ndarray
    linked: np.ndarray
    sig: np.ndarray
    tau: np.ndarray
    rprev: np.ndarray
    theta: np.ndarray
    dmg: np.ndarray
    kappa: np.ndarray
    alpha: np.ndarray
    savg: np.ndarray
    seq: np.ndarray
    counters: np.ndarray = field(default_factory=lambda: np.zeros(mk.N_C, dtype=np.int64))
    energy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    kernel_s: float = 0.0


@dataclass(eq=False)
class Model:
    """Automata + constants + constraints: everything fixed during a run except `fp`'s clock."""

    aut: Automata
    elastic: Elastic
    response: Response | None = None
    fracture: bool = False
    rotations: bool = True
    friction: float = 0.3
    krot: float = 0.0
    relink_stress: float | None = None
    cfl: float = 0.5
    gamma: float = 0.0
    fixm: np.ndarray = field(default=None)  # (N, 6) uint8
    fixv: np.ndarray = field(default=None)  # (N, 6) prescribed velocities
    group: np.ndarray = field(default=None)  # (N,) 1 = driven face, 2 = opposite face
    t_stop: float = math.inf
    skin: float = 0.25  # in units of the smallest spacing
    ke_limit: float = math.inf  # kinetic energy above which the run stops as blown up (J)
    fp: np.ndarray = field(init=False)
    ip: np.ndarray = field(init=False)
    dt: float = field(init=False)
    omega_max: float = field(init=False)

    def __post_init__(self) -> None:
        n = self.aut.size
        if self.fixm is None:
            self.fixm = np.zeros((n, 6), dtype=np.uint8)
        if self.fixv is None:
            self.fixv = np.zeros((n, 6))
        if self.group is None:
            self.group = np.zeros(n, dtype=np.int64)
        if not self.rotations:
            self.fixm[:, 3:] = 1
            self.fixv[:, 3:] = 0.0
        el = self.elastic
        k = stiffness(self.aut, el.shear, el.lam, el.kn, self.krot, rotations=True)
        self.omega_max = omega_max_bound(k, mass_diagonal(self.aut, rotations=True))
        self.dt = 2.0 * self.cfl / self.omega_max
        code = rf.kind_code(self.response)
        fp = np.zeros(mk.N_FP)
        fp[mk.F_DT] = self.dt
        fp[mk.F_G], fp[mk.F_LAM], fp[mk.F_KN], fp[mk.F_KC] = el.shear, el.lam, el.kn, el.contact
        fp[mk.F_MU], fp[mk.F_GAMMA], fp[mk.F_TSTOP] = self.friction, self.gamma, self.t_stop
        fp[mk.F_SKIN] = self.skin * float(self.aut.spacing.min())
        fp[mk.F_KEMAX] = self.ke_limit
        fp[mk.F_SC:mk.F_HDE + 1] = rf.kernel_params(self.response, el.youngs)
        fp[mk.F_KROT] = self.krot
        fp[mk.F_RELINK] = math.inf if self.relink_stress is None else self.relink_stress
        self.fp = fp
        ip = np.zeros(mk.N_IP, dtype=np.int64)
        ip[mk.I_KIND] = code
        ip[mk.I_FRACTURE] = int(self.fracture)
        ip[mk.I_ROT] = int(self.rotations)
        ip[mk.I_RELINK] = int(self.relink_stress is not None)
        self.ip = ip

    @property
    def time(self) -> float:
        return float(self.fp[mk.F_T])

    def new_state(self) -> State:
        """The rest state: undeformed, linked, at rest except the prescribed velocities."""
        a = self.aut
        n, p = a.size, len(a.pairs)
        v = self.fixv[:, :3] * self.fixm[:, :3]
        w = self.fixv[:, 3:] * self.fixm[:, 3:]
        z3 = np.zeros((n, 3))
        return State(x=a.positions.copy(), v=v.copy(), phi=z3.copy(), w=w.copy(), f=z3.copy(), mom=z3.copy(),
                     dx=z3.copy(), dphi=z3.copy(), xref=a.positions.copy(), linked=np.ones(p, dtype=np.int64),
                     sig=np.zeros(p), tau=np.zeros((p, 3)), rprev=a.r0.copy(), theta=np.zeros(n), dmg=np.zeros(n),
                     kappa=np.zeros(n), alpha=np.zeros(n), savg=np.zeros((n, 6)), seq=np.zeros(n))

    def advance(self, st: State, nsteps: int, hist: np.ndarray | None = None, record_every: int = 0) -> int:
        """Run up to `nsteps` steps; returns the kernel status (mca_kernel.OK, NAN, GROWTH, MOVED)."""
        a = self.aut
        if hist is None:
            hist = np.zeros((0, mk.N_H))
        self.ip[mk.I_REC] = record_every
        st.counters[mk.C_ROWS] = 0
        t0 = time.perf_counter()
        mk.advance(st.x, st.v, st.phi, st.w, st.f, st.mom, st.dx, st.dphi, a.positions, st.xref, a.mass, a.inertia,
                   a.volume, self.fixm, self.fixv, self.group, a.pairs[:, 0].copy(), a.pairs[:, 1].copy(), a.r0,
                   a.area, st.linked, st.sig, st.tau, st.rprev, st.theta, st.dmg, st.kappa, st.alpha, st.savg,
                   st.seq, self.fp, self.ip, int(nsteps), hist, st.counters, st.energy)
        st.kernel_s += time.perf_counter() - t0
        status = int(st.counters[mk.C_STATUS])
        return status

    def residual(self, st: State) -> float:
        """Largest force (or moment / spacing) on a free degree of freedom."""
        free_f = np.where(self.fixm[:, :3] == 0, st.f, 0.0)
        free_m = np.where(self.fixm[:, 3:] == 0, st.mom, 0.0) / float(self.aut.spacing.min())
        return float(max(np.abs(free_f).max(initial=0.0), np.abs(free_m).max(initial=0.0)))

    def relaxation_rate(self) -> float:
        """Viscous damping rate for dynamic relaxation: pi c / (4 L_max), c = sqrt(E / rho): an eighth of the
        lowest axial angular frequency of a free-fixed bar of the largest extent.  Measured on bar-compression
        (steps to relax_tol 1e-9, same ramp): n = 4: 6000 / 3500 / 8500 / 17000 steps at 0.5 / 1 / 2 / 4 times
        this rate; n = 6: 9500 at 1x, 20500 at 2x."""
        ext = self.aut.spacing * (np.asarray(self.aut.shape) - 1)
        rho = float(self.aut.mass.sum() / self.aut.volume.sum())
        c = math.sqrt(self.elastic.youngs / rho)
        return math.pi * c / (4.0 * float(ext.max()))


def relax(model: Model, st: State, force_scale: float, tol: float = 1e-8, chunk: int = 500,
          max_steps: int = 2_000_000) -> tuple[int, float, int]:
    """Damped run until max residual force <= tol * force_scale, never before the drive has stopped
    (time >= fp[F_TSTOP]); returns (status, residual, steps)."""
    steps = 0
    res = math.inf
    status = mk.OK
    while steps < max_steps:
        status = model.advance(st, chunk)
        steps += chunk
        res = model.residual(st) / force_scale
        if status != mk.OK or (res <= tol and model.time >= model.fp[mk.F_TSTOP]):
            break
    return status, res, steps


def rebuild_pairs(model: Model, st: State) -> int:
    """Extend the pair list after automata moved beyond the skin; returns the number of pairs added.

    Listed pairs keep their state (an unlinked pair stays listed: it may come back into contact).  Every
    unlisted pair of automata closer than d (1 + 2 skin) -- d = the smallest spacing, the automata's
    diameter -- is added unlinked (r0 = d, contact area the mean of the two cells' face areas), so a
    contact is listed before it closes as long as no automaton moves more than `skin` d between rebuilds.
    """
    aut = model.aut
    d = float(aut.spacing.min())
    cand = cKDTree(st.x).query_pairs(d * (1 + 2 * model.skin), output_type="ndarray").astype(np.int64)
    cand = np.sort(cand, axis=1)
    n = aut.size
    listed = np.sort(aut.pairs, axis=1)
    new = cand[~np.isin(cand[:, 0] * n + cand[:, 1], listed[:, 0] * n + listed[:, 1])]
    st.xref[:] = st.x
    st.counters[mk.C_STATUS] = mk.OK
    if len(new) == 0:
        return 0
    face = aut.volume ** (2.0 / 3.0)
    r = np.linalg.norm(st.x[new[:, 1]] - st.x[new[:, 0]], axis=1)
    model.aut = replace(aut, pairs=np.concatenate([aut.pairs, new]), r0=np.concatenate([aut.r0, np.full(len(new), d)]),
                        area=np.concatenate([aut.area, 0.5 * (face[new[:, 0]] + face[new[:, 1]])]),
                        axis=np.concatenate([aut.axis, np.full(len(new), -1)]))
    st.linked = np.concatenate([st.linked, np.zeros(len(new), dtype=np.int64)])
    st.sig = np.concatenate([st.sig, np.zeros(len(new))])
    st.tau = np.concatenate([st.tau, np.zeros((len(new), 3))])
    st.rprev = np.concatenate([st.rprev, r])
    return int(len(new))
