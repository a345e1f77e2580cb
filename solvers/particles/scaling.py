"""Large-N kernel of the macromolecule model: Verlet list, race-free force passes, prange over particles.

The same model as the solver's fixed-pair-list kernel (seven-root pair force F(r) plus radial
damping delta * rdot, F > 0 attraction), for lattices up to ~10^6 particles on a few cores:

- pairs come from a `neighbours.NeighbourList` (cell list, skin, rebuilt on demand), not from
  the rest lattice; a pair interacts while r < r_cut.  With r_cut between 2a and sqrt(5) a
  (default 2.1 a) the interacting set of a vibrating lattice is exactly the fixed list's
  (all pairs with r0 <= 2a: the force vanishes at 2a, the damping acts out to r_cut, as in
  LAMMPS' dpd/ext cutoff);
- two force passes, both free of write races and bit-identical for any number of threads:
  "gather": particle i sums its own row and writes f[i] only (each pair evaluated twice);
  "slabs" (default): each pair evaluated once (half rows, j > i) and its term added to both
  particles.  Particles are cut into index blocks at least as wide as the largest j - i of the
  list, so a block writes only into itself and the next block; blocks of one colour (even,
  then odd) run in parallel.  Block width and summation order depend on the list only, never
  on the thread count;
- time stepping is velocity Verlet (LAMMPS fix nve): half kick, drift, forces, half kick.  The
  damping in F_{n+1} uses v_{n+1/2}, the velocities at force time (LAMMPS' dpd does the same;
  it is the half-step predictor of the solver's kernel, see integrate.py);
- fixes: FREE, FROZEN (held at rest), PRESCRIBED (x = x_rest + amp sin(omega t + phase)).

Work counter: a pair-step is one interacting pair (i < j, r < r_cut) advanced one step (the
gather evaluates each twice, the slab pass once).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit, prange

from harness.scene import Box, SceneError, lattice_points, lattice_spacing

from .neighbours import NeighbourList, build_neighbours, dist2
from .seven_root import SevenRoot, energy_x, force_x, shell_stiffness

FREE, FROZEN, PRESCRIBED = 0, 1, 2
DONE, EXPIRED = 0, 1
DEFAULT_R_CUT = 2.1  # in units of a: above the 2a shell, below the sqrt(5) a shell
DEFAULT_SKIN = 0.1  # in units of a: list radius 2.2 a < sqrt(5) a keeps 32 entries per bulk particle
FORCE_PASSES = ("slabs", "gather")


@njit(cache=True, inline="always", error_model="numpy")
def pair_term(dx, dy, dz, dvx, dvy, dvz, r2, c, inv_a, delta):
    """Force on i from j (conservative + radial damping), given d = x_j - x_i, dv = v_j - v_i."""
    r = math.sqrt(r2)
    ir = 1.0 / r
    ex = dx * ir
    ey = dy * ir
    ez = dz * ir
    g = force_x(r * inv_a, c)
    if delta != 0.0:
        g += delta * (dvx * ex + dvy * ey + dvz * ez)
    return g * ex, g * ey, g * ez


@njit(cache=True, inline="always", error_model="numpy")
def row_sum(x, v, start, index, i, c, inv_a, rc2, delta, f, half):
    """Sum of row i's pair terms (pairs with r^2 < rc2).  half: only j > i, and each term is also
    subtracted from f[j] (Newton's third law; the slab pass).  One body for both force passes."""
    xi = x[i, 0]
    yi = x[i, 1]
    zi = x[i, 2]
    vxi = v[i, 0]
    vyi = v[i, 1]
    vzi = v[i, 2]
    fx = 0.0
    fy = 0.0
    fz = 0.0
    for p in range(start[i], start[i + 1]):
        j = index[p]
        if half and j < i:
            continue
        dx = x[j, 0] - xi
        dy = x[j, 1] - yi
        dz = x[j, 2] - zi
        r2 = dx * dx + dy * dy + dz * dz
        if r2 >= rc2:
            continue
        tx, ty, tz = pair_term(dx, dy, dz, v[j, 0] - vxi, v[j, 1] - vyi, v[j, 2] - vzi, r2, c, inv_a, delta)
        fx += tx
        fy += ty
        fz += tz
        if half:
            f[j, 0] -= tx
            f[j, 1] -= ty
            f[j, 2] -= tz
    return fx, fy, fz


@njit(cache=True, parallel=True, error_model="numpy")
def gather_forces(x, v, start, index, c, inv_a, rc2, delta, f):
    """f[i] = sum over row i of the pair terms (pairs with r^2 < rc2); overwrites f."""
    for i in prange(x.shape[0]):
        f[i, 0], f[i, 1], f[i, 2] = row_sum(x, v, start, index, i, c, inv_a, rc2, delta, f, False)


@njit(cache=True, parallel=True, error_model="numpy")
def slab_forces(x, v, start, index, c, inv_a, rc2, delta, f, block):
    """f = sum of pair terms, each pair (j > i) evaluated once; two-colour index blocks of width
    `block` >= the list's largest j - i (see `list_reach`), so no two threads write one slot."""
    n = x.shape[0]
    for i in prange(n):
        f[i, 0] = 0.0
        f[i, 1] = 0.0
        f[i, 2] = 0.0
    nb = (n + block - 1) // block
    for colour in range(2):
        for q in prange((nb - colour + 1) // 2):
            b = 2 * q + colour
            for i in range(b * block, min((b + 1) * block, n)):
                fx, fy, fz = row_sum(x, v, start, index, i, c, inv_a, rc2, delta, f, True)
                f[i, 0] += fx
                f[i, 1] += fy
                f[i, 2] += fz


@njit(cache=True, error_model="numpy")
def list_reach(start, index):
    """Largest j - i over the list (rows ascending): the smallest valid slab block width (>= 1)."""
    reach = 1
    for i in range(start.shape[0] - 1):
        if start[i + 1] > start[i]:
            reach = max(reach, index[start[i + 1] - 1] - i)
    return reach


@njit(cache=True, error_model="numpy")
def _forces(x, v, start, index, c, inv_a, rc2, delta, f, block):
    if block > 0:
        slab_forces(x, v, start, index, c, inv_a, rc2, delta, f, block)
    else:
        gather_forces(x, v, start, index, c, inv_a, rc2, delta, f)


@njit(cache=True, inline="always", error_model="numpy")
def drift(x, v, f, x_rest, amp, at, i, kd, scale, omega, phase, t0, t1, h, dt, inv_dt):
    """First half of a velocity-Verlet step of particle i, state row `at` ((i,) or (i, k)): half kick
    and drift (FREE), the drive over [t0, t1] with amplitude amp[i] * scale (PRESCRIBED) or rest
    (FROZEN).  Shared by the single run (scale 1.0: amp * 1.0 is amp exactly) and the ensemble.
    Index tuples, not row views: a view costs a reference count per particle in the hot loop."""
    if kd == FREE:
        for d in range(3):
            v[at + (d,)] += h * f[at + (d,)]
            x[at + (d,)] += dt * v[at + (d,)]
    elif kd == PRESCRIBED:
        s0 = math.sin(omega * t0 + phase)
        s1 = math.sin(omega * t1 + phase)
        for d in range(3):
            ak = amp[i, d] * scale
            v[at + (d,)] = ak * (s1 - s0) * inv_dt
            x[at + (d,)] = x_rest[i, d] + ak * s1
    else:
        for d in range(3):
            v[at + (d,)] = 0.0


@njit(cache=True, inline="always", error_model="numpy")
def kick(v, f, amp, at, i, kd, scale, omega, phase, t1, h):
    """Second half of the step of particle i (row `at`): half kick (FREE) or the drive's velocity at t1."""
    if kd == FREE:
        for d in range(3):
            v[at + (d,)] += h * f[at + (d,)]
    elif kd == PRESCRIBED:
        cs = math.cos(omega * t1 + phase)
        for d in range(3):
            v[at + (d,)] = amp[i, d] * scale * omega * cs


@njit(cache=True, inline="always", error_model="numpy")
def kinetic_dt(v, at, mass, dt):
    """KE dt of row `at` of v: its step's share of the time integral of the kinetic energy."""
    return 0.5 * mass * (v[at + (0,)] * v[at + (0,)] + v[at + (1,)] * v[at + (1,)] + v[at + (2,)] * v[at + (2,)]) * dt


@njit(cache=True, parallel=True, error_model="numpy")
def advance(x, v, f, x_rest, kind, amp, phase, omega, mass, dt, step0, n_steps, start, index, x_ref, half_skin,
            c, inv_a, rc2, delta, hot, resume, block):
    """Velocity-Verlet steps from step0 until n_steps are done or the list expires.

    Returns (steps completed, status).  On EXPIRED the step in progress has been drifted (x at
    t_{n+1}, v = v_{n+1/2}) but has no forces yet: rebuild the list and call again with
    resume=True, which starts at the force pass.  hot (N,) accumulates KE_i dt (if len N).
    block > 0: slab force pass of that block width; 0: gather.
    """
    n = x.shape[0]
    lim2 = half_skin * half_skin
    h = 0.5 * dt / mass
    inv_dt = 1.0 / dt
    with_hot = hot.shape[0] == n
    s = 0
    while s < n_steps:
        t0 = (step0 + s) * dt
        t1 = (step0 + s + 1) * dt
        if not resume:
            over = 0
            for i in prange(n):
                drift(x, v, f, x_rest, amp, (i,), i, kind[i], 1.0, omega, phase[i], t0, t1, h, dt, inv_dt)
                if not dist2(x, (i,), x_ref, (i,)) <= lim2:
                    over += 1
            if over > 0:
                return s, EXPIRED
        resume = False
        _forces(x, v, start, index, c, inv_a, rc2, delta, f, block)
        for i in prange(n):
            kick(v, f, amp, (i,), i, kind[i], 1.0, omega, phase[i], t1, h)
            if with_hot:
                hot[i] += kinetic_dt(v, (i,), mass, dt)
        s += 1
    return s, DONE


@njit(cache=True, error_model="numpy")  # serial: a check, not a hot loop (compiles faster)
def _pair_energy(x, start, index, c, a, rc2):
    """Per-particle share of U = sum over pairs i < j of a * int_2^{r/a} F dx (U = 0 at 2a)."""
    n = x.shape[0]
    out = np.zeros(n)
    inv_a = 1.0 / a
    for i in range(n):
        u = 0.0
        for p in range(start[i], start[i + 1]):
            j = index[p]
            if j <= i:
                continue
            r2 = dist2(x, (j,), x, (i,))
            if r2 < rc2:
                u += energy_x(2.0, math.sqrt(r2) * inv_a, c)
        out[i] = u * a
    return out


@njit(cache=True, error_model="numpy")  # serial: a check, not a hot loop (compiles faster)
def _count_pairs(x, start, index, rc2):
    n = x.shape[0]
    out = np.zeros(n, dtype=np.int64)
    for i in range(n):
        m = 0
        for p in range(start[i], start[i + 1]):
            j = index[p]
            if j > i and dist2(x, (j,), x, (i,)) < rc2:
                m += 1
        out[i] = m
    return out


def check_range(r_cut: float, skin: float, dt: float) -> None:
    """SceneError unless 2 < r_cut <= 4 (units of a), 0 < skin <= 2 (units of a) and 0 < dt (s)."""
    if not (math.isfinite(r_cut) and 2.0 < r_cut <= 4.0):
        raise SceneError(f"r_cut={r_cut!r} (units of a) is out of range; allowed: number in (2, 4] (the force "
                         "ends at 2a; pairs resting at 2a must stay inside the interaction range)")
    if not (math.isfinite(skin) and 0.0 < skin <= 2.0):
        raise SceneError(f"skin={skin!r} (units of a) is out of range; allowed: number in (0, 2]")
    if not (math.isfinite(dt) and dt > 0.0):
        raise SceneError(f"dt={dt!r} is out of range; allowed: number in (0, inf) s")


def initial_state(x_rest: np.ndarray, kind: np.ndarray | None, amp: np.ndarray | None, phase: np.ndarray | None,
                  x0: np.ndarray | None, v0: np.ndarray | None) -> tuple[np.ndarray, ...]:
    """(x_rest, kind, amp, phase, x, v): rest positions and fixes as contiguous arrays (defaults: every
    particle FREE, no drive) and the initial state of the undriven particles (x0 default x_rest, v0
    default 0; FROZEN ones at rest).  Driven particles are placed by the caller (single run or replicas)."""
    n = x_rest.shape[0]
    x_rest = np.ascontiguousarray(x_rest, dtype=np.float64)
    kind = np.zeros(n, dtype=np.int8) if kind is None else np.ascontiguousarray(kind, dtype=np.int8)
    amp = np.zeros((n, 3)) if amp is None else np.ascontiguousarray(amp, dtype=np.float64)
    phase = np.zeros(n) if phase is None else np.ascontiguousarray(phase, dtype=np.float64)
    x = x_rest.copy() if x0 is None else np.array(x0, dtype=np.float64)
    x[kind == FROZEN] = x_rest[kind == FROZEN]
    v = np.zeros((n, 3)) if v0 is None else np.array(v0, dtype=np.float64)
    v[kind == FROZEN] = 0.0
    return x_rest, kind, amp, phase, x, v


@dataclass(eq=False, kw_only=True)
class LatticeRun:
    """State shared by the runs of the large-N kernels (single run, ensemble) and their step driver:
    `advance` calls the subclass's kernel until the list expires, checks the state, rebuilds the
    list and resumes at the force pass."""

    x: np.ndarray
    v: np.ndarray
    f: np.ndarray
    x_rest: np.ndarray
    kind: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    mass: float
    a: float
    dt: float
    coeffs: np.ndarray
    nl: NeighbourList
    hot: np.ndarray
    r_cut: float
    step: int = 0
    status: str = "ok"
    reason: str = ""

    def _steps(self, n_steps: int, resume: bool) -> tuple[int, int]:
        """Run the numba kernel from self.step: (steps completed, DONE or EXPIRED)."""
        raise NotImplementedError

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        """Why the state is unstable (non-finite, or a particle outside [lo, hi]); "" if it is not."""
        raise NotImplementedError

    def _rebuild(self, step: int) -> None:
        raise NotImplementedError

    def advance(self, n_steps: int) -> int:
        """Advance n_steps (fewer if the run becomes unstable: status, reason set, sums kept); rebuilds the
        list on demand."""
        done = 0
        resume = False
        lo = self.x_rest.min(axis=0) - self.a
        hi = self.x_rest.max(axis=0) + self.a
        while done < n_steps and self.status == "ok":
            s, code = self._steps(n_steps - done, resume)
            done += s
            self.step += s
            resume = False
            if code == EXPIRED:
                reason = self._instability(lo, hi)
                if reason:
                    self.status, self.reason = "unstable", reason
                else:
                    self._rebuild(self.step)
                    resume = True
        if resume:  # stopped between drift and forces: finish the step
            self._steps(1, True)
            done += 1
            self.step += 1
        return done


@dataclass(eq=False, kw_only=True)
class KernelRun(LatticeRun):
    """State of one run of the large-N kernel (positions, velocities, forces, list, fixes, sums)."""

    omega: float
    delta: float
    force_pass: str = "slabs"

    @classmethod
    def start(cls, x_rest: np.ndarray, mass: float, a: float, model: SevenRoot, delta: float, dt: float,
              v0: np.ndarray | None = None, x0: np.ndarray | None = None, kind: np.ndarray | None = None,
              amp: np.ndarray | None = None, phase: np.ndarray | None = None, omega: float = 0.0,
              r_cut: float = DEFAULT_R_CUT, skin: float = DEFAULT_SKIN, hotness: bool = False,
              force_pass: str = "slabs") -> KernelRun:
        """Set up a run at t = 0: list built on x0 (default x_rest), forces F(x0, v0) computed."""
        check_range(r_cut, skin, dt)
        if force_pass not in FORCE_PASSES:
            raise SceneError(f"force_pass={force_pass!r} is not allowed; allowed: {', '.join(FORCE_PASSES)}")
        if not (math.isfinite(delta) and delta >= 0.0):
            raise SceneError(f"delta={delta!r} is out of range; allowed: number in [0, inf) N s/m")
        x_rest, kind, amp, phase, x, v = initial_state(x_rest, kind, amp, phase, x0, v0)
        n = x_rest.shape[0]
        drv = kind == PRESCRIBED
        x[drv] = x_rest[drv] + amp[drv] * np.sin(phase[drv])[:, None]
        v[drv] = amp[drv] * (omega * np.cos(phase[drv]))[:, None]
        nl = build_neighbours(x, r_cut * a, skin * a)
        run = cls(x=x, v=v, f=np.zeros((n, 3)), x_rest=x_rest, kind=kind, amp=amp, phase=phase, omega=float(omega),
                  mass=float(mass), a=float(a), dt=float(dt), coeffs=model.coeffs(), delta=float(delta), nl=nl,
                  hot=np.zeros(n if hotness else 0), r_cut=float(r_cut) * a, force_pass=force_pass)
        _forces(run.x, run.v, nl.start, nl.index, run.coeffs, 1.0 / run.a, run.r_cut**2, run.delta, run.f,
                run.block)
        return run

    @property
    def block(self) -> int:
        """Slab block width for the current list (0: gather pass)."""
        if self.force_pass == "gather":
            return 0
        if getattr(self, "_block_for", None) is not self.nl.index:
            self._block = int(list_reach(self.nl.start, self.nl.index))
            self._block_for = self.nl.index
        return self._block

    @property
    def size(self) -> int:
        return int(self.x.shape[0])

    def _steps(self, n_steps: int, resume: bool) -> tuple[int, int]:
        return advance(self.x, self.v, self.f, self.x_rest, self.kind, self.amp, self.phase, self.omega, self.mass,
                       self.dt, self.step, n_steps, self.nl.start, self.nl.index, self.nl.x_ref, 0.5 * self.nl.skin,
                       self.coeffs, 1.0 / self.a, self.r_cut**2, self.delta, self.hot, resume, self.block)

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        if not np.isfinite(self.x).all() or not np.isfinite(self.v).all():
            return f"NaN/Inf in the state at step {self.step}; sums kept"
        if (self.x < lo).any() or (self.x > hi).any():
            return f"a particle left the bar's neighbourhood (more than a outside) at step {self.step}; sums kept"
        return ""

    def _rebuild(self, step: int) -> None:
        self.nl.rebuild(self.x, step)

    def pair_count(self) -> int:
        """Interacting pairs (i < j, r < r_cut) at the current positions."""
        return int(_count_pairs(self.x, self.nl.start, self.nl.index, self.r_cut**2).sum())

    def potential_energy(self) -> float:
        """U(x) (J) with U = 0 for pairs at 2a; summed per particle, then in index order (deterministic)."""
        return float(_pair_energy(self.x, self.nl.start, self.nl.index, self.coeffs, self.a, self.r_cut**2).sum())

    def kinetic_energy(self) -> float:
        return float(0.5 * self.mass * np.einsum("ij,ij->", self.v, self.v))

    @property
    def nbytes(self) -> int:
        """Memory of the run's arrays: state, fixes, sums and the neighbour list (bytes)."""
        arrays = (self.x, self.v, self.f, self.x_rest, self.kind, self.amp, self.phase, self.hot)
        return int(sum(a.nbytes for a in arrays) + self.nl.nbytes)


def bench_lattice(n: int, box: Box | None = None, density: float = 2800.0) -> tuple[np.ndarray, float, float]:
    """Rest positions (N, 3), spacing a and particle mass of the lattice n x n x (3n-2) in the bar."""
    box = box or Box()
    x = lattice_points(box, n)
    return x, lattice_spacing(box, n), density * box.volume / x.shape[0]


def omega_bound(model: SevenRoot, a: float, mass: float) -> float:
    """Upper bound on the lattice's highest angular frequency (Gershgorin on the rest Hessian).

    At rest every pair sits on a root, so its Hessian block is k_s e e^T (k_s = dF/dr of its
    shell); the absolute row sum of a bulk particle's rows is at most 2 sum_s k_s N_s max_c
    sum_b |e_c e_b|, with N_s neighbours in shell s.  Cheap at any N (no eigenproblem).
    """
    k = np.abs(shell_stiffness(model, a))
    offsets = np.array([(i, j, m) for i in (-2, -1, 0, 1, 2) for j in (-2, -1, 0, 1, 2) for m in (-2, -1, 0, 1, 2)
                        if 0 < i * i + j * j + m * m <= 4], dtype=float)
    r = np.linalg.norm(offsets, axis=1)
    e = offsets / r[:, None]
    shell = np.rint(r**2).astype(int) - 1  # 1, 2, 3, 4 -> shells 0..3
    ks = k[shell]
    row = np.abs(e[:, :, None] * e[:, None, :]).sum(axis=2)  # (P, 3): sum_b |e_c e_b| for each c
    bound = 2.0 * (ks[:, None] * row).sum(axis=0).max()
    return math.sqrt(bound / mass)


def rows_from_benchmark_json(path: str | Path) -> list[dict]:
    """Rows {N, ns_per_pair_step, bytes_per_particle, threads, force_pass, name} of the scaling benchmarks
    in a pytest-benchmark JSON file (benchmarks whose extra_info has those keys), sorted by N."""
    data = json.loads(Path(path).read_text())
    rows = []
    for b in data.get("benchmarks", []):
        info = b.get("extra_info", {})
        if "ns_per_pair_step" in info and "bytes_per_particle" in info and "particles" in info:
            rows.append({"N": int(info["particles"]), "ns_per_pair_step": float(info["ns_per_pair_step"]),
                         "bytes_per_particle": float(info["bytes_per_particle"]),
                         "threads": int(info.get("threads", 0)), "force_pass": info.get("force_pass", ""),
                         "name": b.get("name", "")})
    return sorted(rows, key=lambda r: (r["N"], r["force_pass"], r["threads"]))
