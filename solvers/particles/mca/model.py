"""MCA model: material constants, the automata's state, and two ways of running it: `Model.advance` in time,
`relax` with viscous damping to a residual force (dynamic relaxation, for static scenes).

The many-body coefficient D = 1 - 2G/(3K) is the one for which the pair stress is Hooke's law in every direction
(1 - 2G/K gives nu = 0.19 for duralumin; without the term nu_eff = 0): derived in docs/physics.md, "The MCA
solver in detail", "The many-body coefficient".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from pcverify.scene import Response, Scene, SceneError

from . import contact as ct
from . import kernel as mk
from . import response as rf
from .automata import Automata
from .kernels import timed
from .parameters import COEFFICIENTS
from .stiffness import mass_diagonal, omega_max_bound, stiffness


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

    @classmethod
    def of(cls, scene: Scene, p: dict[str, Any]) -> Elastic:
        """The constants of the scene's material with the solver parameters' many-body term and coefficient."""
        mat = scene.material
        return cls(mat.youngs_modulus, mat.poisson_ratio, many_body=p["many_body"], coefficient=p["coefficient"])

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
class Model:
    """Automata + constants + fixes + loads: everything fixed during a run.  `params` are the kernel's scalars
    (a NamedTuple: replace fields with `_replace` to change the drive's stop time between runs)."""

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
    fixm: np.ndarray = field(default=None)  # (N, 6) uint8: kernel.FREE or PRESCRIBED
    fixv: np.ndarray = field(default=None)  # (N, 6) prescribed velocities
    group: np.ndarray = field(default=None)  # (N,) 1 = driven face, 2 = opposite face
    t_stop: float = math.inf
    skin: float = 0.25  # in units of the smallest spacing
    ke_limit: float = math.inf  # kinetic energy above which the run stops as blown up (J)
    load: np.ndarray | None = None  # (N, 3) external forces (N), constant
    contact: ct.ContactLaw | None = None  # the contact law of body 2's surface on body 1's (aut.body set)
    step_automata: Automata | None = None  # automata whose stiffness bounds the step (default aut)
    frame: np.ndarray | None = None  # (N, 3) reference velocities of the damping (ramped with the drive)
    params: mk.Params = field(init=False)
    dt: float = field(init=False)
    omega_max: float = field(init=False)
    kernel_s: float = field(init=False, default=0.0)  # seconds in the kernel's steps (dispatch excluded)

    def __post_init__(self) -> None:
        n = self.aut.size
        if self.fixm is None:
            self.fixm = np.zeros((n, 6), dtype=np.uint8)
        if self.fixv is None:
            self.fixv = np.zeros((n, 6))
        if self.group is None:
            self.group = np.zeros(n, dtype=np.int64)
        if not self.rotations:
            self.fixm[:, 3:] = mk.PRESCRIBED
            self.fixv[:, 3:] = 0.0
        el = self.elastic
        bound = self.aut if self.step_automata is None else self.step_automata
        k = stiffness(bound, el.shear, el.lam, el.kn, self.krot, rotations=True)
        self.omega_max = omega_max_bound(k, mass_diagonal(bound, rotations=True))
        self.dt = 2.0 * self.cfl / self.omega_max
        sc, kdp, sy, hp, sd, hde = rf.kernel_params(self.response, el.youngs)
        self.params = mk.Params(
            dt=float(self.dt), shear=float(el.shear), lam=float(el.lam), kn=float(el.kn), kc=float(el.contact),
            mu=float(self.friction), gamma=float(self.gamma), t_stop=float(self.t_stop),
            skin=self.skin * float(self.aut.spacing.min()), ke_max=float(self.ke_limit), krot=float(self.krot),
            relink=math.inf if self.relink_stress is None else float(self.relink_stress), sigma_c=float(sc),
            kdp=float(kdp), sigma_y=float(sy), hp=float(hp), sigma_d=float(sd), hde=float(hde),
            kind=rf.kind_code(self.response), fracture=bool(self.fracture), relink_on=self.relink_stress is not None,
            record_every=0)

    @property
    def free_dofs(self) -> int:
        """The degrees of freedom the run integrates freely (translations, and rotations where the automata
        rotate; not the held or prescribed ones): the solution's `unknowns`."""
        return int(np.count_nonzero(self.fixm == mk.FREE))

    def work(self, st: mk.State) -> dict[str, Any]:
        """The run's work counters (the solution's `work`): pair-steps, time steps, kernel seconds, unknowns."""
        return {"pair_steps": int(st.counters[mk.C_PAIRSTEPS]), "time_steps": int(st.counters[mk.C_STEPS]),
                "kernel_s": self.kernel_s, "unknowns": self.free_dofs}

    @property
    def inelastic(self) -> bool:
        """Whether the automata carry the inelastic state (a response function or fracture)."""
        return self.params.kind != 0 or self.params.fracture

    def new_state(self, hist_rows: int = 0, peak: bool = False) -> mk.State:
        """The rest state: undeformed, linked, at rest except the prescribed velocities; room for `hist_rows`
        history rows; with `peak`, the driven face's largest reaction tracked every step (kernel.State.peak)."""
        a = self.aut
        n, p = a.size, len(a.pairs)
        v = self.fixv[:, :3] * self.fixm[:, :3]
        w = self.fixv[:, 3:] * self.fixm[:, 3:]
        z3 = np.zeros((n, 3))
        rot = mk.Rotation(phi=z3.copy(), w=w.copy(), mom=z3.copy(), dphi=z3.copy(), inertia=a.inertia) \
            if self.rotations else None
        inel = mk.Inelastic(dmg=np.zeros(n), kappa=np.zeros(n), alpha=np.zeros(n), savg=np.zeros((n, 6)),
                            seq=np.zeros(n), mfac=np.ones(n), smean=np.zeros(n)) if self.inelastic else None
        load = None if self.load is None else mk.Load(np.asarray(self.load, dtype=float))
        return mk.State(x0=a.positions, mass=a.mass, vol=a.volume, fixm=self.fixm, fixv=self.fixv, group=self.group,
                        pi=a.pairs[:, 0].copy(), pj=a.pairs[:, 1].copy(), r0=a.r0, area=a.area,
                        x=a.positions.copy(), v=v.copy(), f=z3.copy(), dx=z3.copy(), xref=a.positions.copy(),
                        linked=np.ones(p, dtype=np.int64), sig=np.zeros(p), tau=np.zeros((p, 3)), rprev=a.r0.copy(),
                        theta=np.zeros(n), clock=np.zeros(1), counters=np.zeros(mk.N_C, dtype=np.int64),
                        energy=np.zeros(mk.N_E), hist=np.zeros((hist_rows, mk.N_H)), rot=rot, inel=inel, load=load,
                        contact=None if self.contact is None else ct.new_state(a, a.positions, self.contact,
                                                                               self.params.skin),
                        frame=None if self.frame is None else mk.Frame(np.asarray(self.frame, dtype=float)),
                        peak=np.array([-np.inf, 0.0, 0.0]) if peak else None)

    def advance(self, st: mk.State, nsteps: int, record_every: int = 0) -> int:
        """Run up to `nsteps` steps, a history row every `record_every` steps (rows from 0 in st.hist); returns
        the kernel status (kernel.OK, NAN, GROWTH, MOVED)."""
        st.counters[mk.C_ROWS] = 0
        self.kernel_s += timed("mechanics", st, self.params._replace(record_every=int(record_every)), int(nsteps))
        return int(st.counters[mk.C_STATUS])

    def residual(self, st: mk.State) -> float:
        """Largest force (or moment / spacing) on a free degree of freedom."""
        free_f = np.where(self.fixm[:, :3] == mk.FREE, st.f, 0.0)
        mom = st.rot.mom if st.rot is not None else np.zeros_like(st.f)
        free_m = np.where(self.fixm[:, 3:] == mk.FREE, mom, 0.0) / float(self.aut.spacing.min())
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


def relax(model: Model, st: mk.State, force_scale: float, tol: float = 1e-8, chunk: int = 500,
          max_steps: int = 2_000_000) -> tuple[int, float, int]:
    """Damped run until max residual force <= tol * force_scale, never before the drive has stopped
    (time >= params.t_stop); returns (status, residual, steps)."""
    steps = 0
    res = math.inf
    status = mk.OK
    while steps < max_steps:
        take = min(chunk, max_steps - steps)  # max_steps is a hard cap, not rounded up to a chunk
        status = model.advance(st, take)
        steps += take
        res = model.residual(st) / force_scale
        if status != mk.OK or (res <= tol and st.clock[0] >= model.params.t_stop):
            break
    return status, res, steps


def relax_status(code: int, res: float, tol: float, steps: int, max_steps: int) -> tuple[str, str]:
    """(Solution status, reason) of a relaxation that ended with kernel status `code` and residual `res`."""
    if code in (mk.NAN, mk.GROWTH):
        return "unstable", f"{mk.STATUS_TEXT[code]} after {steps} steps; state at that step kept"
    if code == mk.MOVED:
        return "failed", mk.STATUS_TEXT[code]
    if not res <= tol:
        return "failed", f"residual {res:.3g} above relax_tol {tol:g} after {steps} steps (max_steps {max_steps})"
    return "ok", ""


def rebuild_pairs(model: Model, st: mk.State) -> tuple[mk.State, int]:
    """Extend the pair list (and relist the contact candidates) after automata moved beyond the skin; the new
    state and the number of pairs added.  Listed pairs keep their state; every unlisted pair closer than
    d (1 + 2 skin), d the smallest spacing, is added unlinked (r0 = d), so a contact is listed before it closes."""
    aut = model.aut
    d = float(aut.spacing.min())
    cand = cKDTree(st.x).query_pairs(d * (1 + 2 * model.skin), output_type="ndarray").astype(np.int64)
    cand = np.sort(cand, axis=1)
    if aut.body is not None:  # bodies meet through the contact, never through pairs
        cand = cand[aut.body[cand[:, 0]] == aut.body[cand[:, 1]]]
    n = aut.size
    listed = np.sort(aut.pairs, axis=1)
    new = cand[~np.isin(cand[:, 0] * n + cand[:, 1], listed[:, 0] * n + listed[:, 1])]
    st.xref[:] = st.x
    st.counters[mk.C_STATUS] = mk.OK
    if st.contact is not None:
        st = st._replace(contact=ct.relisted(st.contact, aut, st.x, model.params.skin))
    if len(new) == 0:
        return st, 0
    face = aut.volume ** (2.0 / 3.0)
    r = np.linalg.norm(st.x[new[:, 1]] - st.x[new[:, 0]], axis=1)
    model.aut = aut = replace(aut, pairs=np.concatenate([aut.pairs, new]),
                              r0=np.concatenate([aut.r0, np.full(len(new), d)]),
                              area=np.concatenate([aut.area, 0.5 * (face[new[:, 0]] + face[new[:, 1]])]),
                              axis=np.concatenate([aut.axis, np.full(len(new), -1)]))
    st = st._replace(pi=aut.pairs[:, 0].copy(), pj=aut.pairs[:, 1].copy(), r0=aut.r0, area=aut.area,
                     linked=np.concatenate([st.linked, np.zeros(len(new), dtype=np.int64)]),
                     sig=np.concatenate([st.sig, np.zeros(len(new))]),
                     tau=np.concatenate([st.tau, np.zeros((len(new), 3))]), rprev=np.concatenate([st.rprev, r]))
    return st, int(len(new))
