"""Contact of two MCA bodies by the segment method, in 3-D: surface facets, contact search, friction.

Facets from the automata without a linked pair on a side, each slave automaton against one facet by its foot
point's barycentric weights, the bonded pair's compressive law, friction at the contact point with its moments,
the reactions of held degrees of freedom, and the candidate list rebuilt with the pair list
(docs/physics.md, "The movable cellular automaton (MCA) model" and "The MCA solver in detail").
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from . import roughness as rg
from .automata import Automata

EDGE = 0.5  # a foot point this far outside a facet (barycentric units) still counts (half a spacing)
# A slave keeps its facet while its foot is at most this far outside it (barycentric units: a fraction of the
# facet's height, about a spacing).  Without it a foot on an edge or corner shared by two facets of a slightly bent
# surface went to whichever its last round-off favoured: in a static-law preload two slaves switched facets 84 times
# in 400 steps, each switch turning the normal by the facets' kink (3.5e-6 rad), and the relaxation never settled
# (the two feet lay 3.4e-7 outside both facets and moved by 1e-11).  A foot's offsets in a pressed contact are
# elastic, of the order of the strain (1.4e-5 at 1 MPa), so 1e-3 holds it with margin; kept beyond its edge the
# slave's weights are clipped (the couple that leaves is taken up, as for EDGE) and its height is over the kept
# facet's plane, off the neighbour's by at most 1e-3 a times their kink; a sliding slave moves on after 1e-3 of a
# spacing more (at 1 m/s: a few dozen steps).
STAY = 1e-3


class ContactLaw(NamedTuple):
    """Constants of the contact (SI units), the axes along which the record resolves the forces (the contact
    axis, the sliding direction), and the dry law: regularised, or static (Coulomb limit mu_s while stuck, mu1
    while slipping, tangential spring kt in Pa/m)."""

    h0: float
    mu0: float
    mu1: float
    sigma0: float
    v_reg: float
    rough: rg.Roughness
    axis: int
    direction: int
    static: bool = False
    mu_s: float = 0.0
    kt: float = 0.0


class ContactState(NamedTuple):
    """Slaves (automata of body 2 on its surface), master facets (triangles of body 1), the candidate list (CSR:
    cand_ptr, cand); per slave (ns) its current contact (facet or -1, weights, normal, ...), per automaton (N)
    its heat and held degrees of freedom, per body (2, 3) the held ones' reactions; the roughness and the law."""

    slave: np.ndarray
    faces: np.ndarray  # (ns, 6) open sides of each slave
    facets: np.ndarray  # (nf, 3)
    side: np.ndarray  # (nf,) side each facet faces
    cand_ptr: np.ndarray
    cand: np.ndarray
    extent: np.ndarray  # (N, 3)
    facet: np.ndarray  # (ns,) int64
    w: np.ndarray  # (ns, 3)
    nrm: np.ndarray  # (ns, 3)
    gap: np.ndarray  # (ns,) h
    area: np.ndarray  # (ns,)
    sigma: np.ndarray  # (ns,) normal stress (compression < 0)
    fric: np.ndarray  # (ns, 3) friction force on the slave
    speed: np.ndarray  # (ns,) |V_t|
    power: np.ndarray  # (ns,) friction power of the current step (W)
    dissipated: np.ndarray  # (ns,) energy dissipated by each slave's friction (J)
    heat: np.ndarray  # (N,) heat received (J)
    held: np.ndarray  # (N, 3) int64: 0 free, 1 held in body 1 (a clamp), 2 held in body 2 (a drive, a platen)
    reaction: np.ndarray  # (2, 3) -sum f over the held degrees of freedom of body 1, body 2 (N)
    impulse: np.ndarray  # (2, 3) time integral of `reaction` (N s)
    held_rot: np.ndarray  # (N, 3) int64: the held rotations, as `held`
    moment: np.ndarray  # (2, 3) the held degrees of freedom's reaction moment about the origin (N m)
    angular_impulse: np.ndarray  # (2, 3) time integral of `moment` (N m s)
    tang: np.ndarray  # (ns, 3) static law: tangential stress of the contact's spring (Pa), resisting the slip
    tnrm: np.ndarray  # (ns, 3) static law: the normal `tang` was last carried with (0: the contact was open)
    slipping: np.ndarray  # (ns,) int64 static law: 1 while the contact slips (kinetic limit), 0 stuck
    rough: rg.RoughState
    law: ContactLaw


def neighbours(aut: Automata) -> np.ndarray:
    """(N, 6) index of the linked face neighbour of each automaton at -x, +x, -y, +y, -z, +z (-1: none)."""
    nb = np.full((aut.size, 6), -1, dtype=np.int64)
    lattice = aut.axis >= 0
    i, j, ax = aut.pairs[lattice, 0], aut.pairs[lattice, 1], aut.axis[lattice]
    up = (aut.positions[j, ax] > aut.positions[i, ax])
    lo, hi = np.where(up, i, j), np.where(up, j, i)
    nb[lo, 2 * ax + 1] = hi
    nb[hi, 2 * ax] = lo
    return nb


def facets(aut: Automata, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (nf, 3) of body `body`'s surface, ordered so that their normals point out of the body, and the
    side each faces (nf,): 2 a + (0 for -e_a, 1 for +e_a)."""
    nb = neighbours(aut)
    mine = aut.body == body if aut.body is not None else np.ones(aut.size, dtype=bool)
    out, sides = [], []
    for ax in range(3):
        e1, e2 = (ax + 1) % 3, (ax + 2) % 3
        for side in (0, 1):
            face = (nb[:, 2 * ax + side] < 0) & mine
            i = np.flatnonzero(face)
            j1 = nb[i, 2 * e1 + 1]
            j2 = nb[i, 2 * e2 + 1]
            ok = (j1 >= 0) & (j2 >= 0)
            i, j1, j2 = i[ok], j1[ok], j2[ok]
            j12 = nb[j1, 2 * e2 + 1]
            ok = (j12 >= 0) & (nb[j2, 2 * e1 + 1] == j12)
            i, j1, j2, j12 = i[ok], j1[ok], j2[ok], j12[ok]
            ok = face[j1] & face[j2] & face[j12]
            i, j1, j2, j12 = i[ok], j1[ok], j2[ok], j12[ok]
            if side == 1:  # e1 x e2 = +e_ax: counter-clockwise seen from outside
                out += [np.stack([i, j1, j12], 1), np.stack([i, j12, j2], 1)]
            else:
                out += [np.stack([i, j12, j1], 1), np.stack([i, j2, j12], 1)]
            sides += [np.full(2 * len(i), 2 * ax + side)]
    if not out:
        return np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(out).astype(np.int64), np.concatenate(sides).astype(np.int64)


def surface(aut: Automata, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Automata of body `body` on its free surface (a missing linked neighbour on some side), and the sides
    (ns, 6) each faces (-x, +x, -y, +y, -z, +z)."""
    mine = aut.body == body if aut.body is not None else np.ones(aut.size, dtype=bool)
    open_side = neighbours(aut) < 0
    idx = np.flatnonzero(mine & np.any(open_side, axis=1)).astype(np.int64)
    return idx, open_side[idx]


def candidates(x: np.ndarray, slave: np.ndarray, faces: np.ndarray, tri: np.ndarray, side: np.ndarray,
               radius: float, skin: float) -> tuple[np.ndarray, np.ndarray]:
    """CSR list (ptr, facet) of the facets each slave may touch, nearest first: centroid within `radius`, the
    slave facing the facet (its open side opposite the facet's) and not behind the facet's plane by more than
    2 skin."""
    if len(tri) == 0 or len(slave) == 0:
        return np.zeros(len(slave) + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    centroid = x[tri].mean(axis=1)
    normal = np.zeros((len(tri), 3))
    normal[np.arange(len(tri)), side // 2] = np.where(side % 2 == 1, 1.0, -1.0)
    opposite = side + 1 - 2 * (side % 2)
    lists = cKDTree(centroid).query_ball_point(x[slave], radius)
    ptr = np.zeros(len(slave) + 1, dtype=np.int64)
    chosen = []
    for s, hits in enumerate(lists):
        f = np.asarray(hits, dtype=np.int64)
        if f.size:
            d = x[slave[s]] - centroid[f]
            keep = faces[s, opposite[f]] & (np.einsum("ij,ij->i", d, normal[f]) > -2.0 * skin)
            f, d = f[keep], d[keep]
            f = f[np.lexsort((f, np.einsum("ij,ij->i", d, d)))]
        chosen.append(f)
        ptr[s + 1] = ptr[s] + f.size
    return ptr, (np.concatenate(chosen) if ptr[-1] else np.zeros(0)).astype(np.int64)


def search_radius(aut: Automata, law: ContactLaw, skin: float) -> float:
    """Centroid distance within which a facet is listed for a slave: h0 + 0.75 d + 2 skin (m)."""
    return law.h0 + 0.75 * float(aut.spacing.max()) + 2.0 * skin


def new_state(aut: Automata, x: np.ndarray, law: ContactLaw, skin: float) -> ContactState:
    """Contact state of body 2's surface automata against body 1's facets, candidates listed at x."""
    tri, side = facets(aut, 0)
    slave, faces = surface(aut, 1)
    ptr, cand = candidates(x, slave, faces, tri, side, search_radius(aut, law, skin), skin)
    ns = len(slave)
    rs = rg.new_state(ns)
    if law.rough.on:
        rg.start(rs, law.rough)
    return ContactState(slave=slave, faces=faces, facets=tri, side=side, cand_ptr=ptr, cand=cand, extent=aut.extent,
                        facet=np.full(ns, -1, dtype=np.int64), w=np.zeros((ns, 3)), nrm=np.zeros((ns, 3)),
                        gap=np.zeros(ns), area=np.zeros(ns), sigma=np.zeros(ns), fric=np.zeros((ns, 3)),
                        speed=np.zeros(ns), power=np.zeros(ns), dissipated=np.zeros(ns), heat=np.zeros(aut.size),
                        held=np.zeros((aut.size, 3), dtype=np.int64), reaction=np.zeros((2, 3)),
                        impulse=np.zeros((2, 3)), held_rot=np.zeros((aut.size, 3), dtype=np.int64),
                        moment=np.zeros((2, 3)), angular_impulse=np.zeros((2, 3)), tang=np.zeros((ns, 3)),
                        tnrm=np.zeros((ns, 3)), slipping=np.zeros(ns, dtype=np.int64), rough=rs, law=law)


def rest_partners(con: ContactState, aut: Automata) -> ContactState:
    """A copy of the contact state with each slave's facet and weights found at the rest positions (the rest
    geometry's partners: in an aligned stack, the automaton right across the interface)."""
    ns = len(con.slave)
    rest = con._replace(facet=np.full(ns, -1, dtype=np.int64), w=np.zeros((ns, 3)), nrm=np.zeros((ns, 3)),
                        gap=np.zeros(ns), area=np.zeros(ns))
    x = aut.positions.copy()
    x[aut.body == 1, con.law.axis] -= 1e-9 * con.law.h0  # just closed (at rest the gap is exactly h0)
    rest = relisted(rest, aut, x, 0.0)
    geometry(x, aut.volume, rest, np.zeros(aut.size))
    return rest


def relisted(con: ContactState, aut: Automata, x: np.ndarray, skin: float) -> ContactState:
    """The same contact state with its candidate list rebuilt at positions x."""
    ptr, cand = candidates(x, con.slave, con.faces, con.facets, con.side, search_radius(aut, con.law, skin), skin)
    return con._replace(cand_ptr=ptr, cand=cand)


@njit(inline="always")
def _foot(x, con, f, k):
    """Slave automaton k over facet f: (h, wa, wb, wd, n0, n1, n2), its height over the facet's plane, its foot
    point's barycentric weights (unclipped) and the facet's outward unit normal."""
    a = con.facets[f, 0]
    b = con.facets[f, 1]
    d = con.facets[f, 2]
    e10 = x[b, 0] - x[a, 0]
    e11 = x[b, 1] - x[a, 1]
    e12 = x[b, 2] - x[a, 2]
    e20 = x[d, 0] - x[a, 0]
    e21 = x[d, 1] - x[a, 1]
    e22 = x[d, 2] - x[a, 2]
    m0 = e11 * e22 - e12 * e21
    m1 = e12 * e20 - e10 * e22
    m2 = e10 * e21 - e11 * e20
    area2 = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    m0 /= area2
    m1 /= area2
    m2 /= area2
    h = m0 * (x[k, 0] - x[a, 0]) + m1 * (x[k, 1] - x[a, 1]) + m2 * (x[k, 2] - x[a, 2])
    p0 = x[k, 0] - h * m0
    p1 = x[k, 1] - h * m1
    p2 = x[k, 2] - h * m2
    wa = _sub_area(x[b, 0] - p0, x[b, 1] - p1, x[b, 2] - p2, x[d, 0] - p0, x[d, 1] - p1, x[d, 2] - p2,
                   m0, m1, m2) / area2
    wb = _sub_area(x[d, 0] - p0, x[d, 1] - p1, x[d, 2] - p2, x[a, 0] - p0, x[a, 1] - p1, x[a, 2] - p2,
                   m0, m1, m2) / area2
    return h, wa, wb, 1.0 - wa - wb, m0, m1, m2


@njit(cache=True)
def geometry(x, vol, con, theta_new):
    """Pass 1 of the contact: each slave's facet, weights, normal and height; the contacts' volume strains
    0.5 S (h - h0) / Omega added to theta_new (k's, and the facet automata's by their weights).  A slave keeps
    its current facet while that facet is listed, the slave within h0 of its plane and the foot at most STAY
    outside it (barycentric units); only then are the listed facets searched (the module's STAY says why)."""
    law = con.law
    h0 = law.h0
    for s in range(con.slave.shape[0]):
        k = con.slave[s]
        best = -1
        bmin = -1e300
        bh = 0.0
        b0 = b1 = b2 = 0.0
        n0 = n1 = n2 = 0.0
        old = con.facet[s]
        if old >= 0:
            for c in range(con.cand_ptr[s], con.cand_ptr[s + 1]):
                if con.cand[c] == old:
                    h, wa, wb, wd, m0, m1, m2 = _foot(x, con, old, k)
                    low = min(wa, wb, wd)
                    if -h0 < h < h0 and low >= -STAY:
                        best, bmin, bh, b0, b1, b2, n0, n1, n2 = old, low, h, wa, wb, wd, m0, m1, m2
                    break
        if best < 0:
            for c in range(con.cand_ptr[s], con.cand_ptr[s + 1]):
                f = con.cand[c]
                h, wa, wb, wd, m0, m1, m2 = _foot(x, con, f, k)
                if h <= -h0 or h >= h0:
                    continue
                low = min(wa, wb, wd)
                if low > bmin:
                    best, bmin, bh, b0, b1, b2, n0, n1, n2 = f, low, h, wa, wb, wd, m0, m1, m2
                    if low >= 0.0:  # the foot lies in this facet: the nearest containing one is taken
                        break
        if best < 0 or bmin < -EDGE:
            con.facet[s] = -1
            continue
        b0 = max(b0, 0.0)
        b1 = max(b1, 0.0)
        b2 = max(b2, 0.0)
        tot = b0 + b1 + b2
        con.facet[s] = best
        con.w[s, 0] = b0 / tot
        con.w[s, 1] = b1 / tot
        con.w[s, 2] = b2 / tot
        con.nrm[s, 0] = n0
        con.nrm[s, 1] = n1
        con.nrm[s, 2] = n2
        con.gap[s] = bh
        ax = 0
        if abs(n1) > abs(n0):
            ax = 1
        if abs(n2) > max(abs(n0), abs(n1)):
            ax = 2
        area = con.extent[k, (ax + 1) % 3] * con.extent[k, (ax + 2) % 3]
        con.area[s] = area
        e = 0.5 * area * (bh - h0)
        theta_new[k] += e / vol[k]
        for v in range(3):
            theta_new[con.facets[best, v]] += con.w[s, v] * e / vol[con.facets[best, v]]


@njit(inline="always")
def _sub_area(u0, u1, u2, v0, v1, v2, n0, n1, n2):
    """n . (u x v): twice the signed area of a sub-triangle."""
    return n0 * (u1 * v2 - u2 * v1) + n1 * (u2 * v0 - u0 * v2) + n2 * (u0 * v1 - u1 * v0)


@njit(cache=True)
def forces(x, v, f, theta, mass, kn, lam, dt, con, rot):
    """Pass 2 of the contact (after the volume strains are updated): normal stress, friction, each slave's
    friction power and tangential speed, and the forces on each slave and its facet's automata (module
    docstring).  The normal force acts at the centres, as the gradient of the contact's elastic energy: applied
    at c, its moments on the facet's automata would do work on their spins that no energy holds (measured: the
    sliding energy balance 2.5e-6 of the drive's work instead of 2.3e-7); its couple when a clipped foot lies
    up to EDGE outside the facet is taken up by moments on the facet's automata by their weights.  rot None:
    forces at the centres, no moments, slip from the centres' velocities."""
    law = con.law
    h0 = law.h0
    for s in range(con.slave.shape[0]):
        con.power[s] = 0.0
        con.speed[s] = 0.0
        con.sigma[s] = 0.0
        con.fric[s, 0] = 0.0
        con.fric[s, 1] = 0.0
        con.fric[s, 2] = 0.0
        fct = con.facet[s]
        if fct < 0:
            if law.static:  # an open contact forgets its spring
                for c in range(3):
                    con.tang[s, c] = 0.0
                    con.tnrm[s, c] = 0.0
                con.slipping[s] = 0
            continue
        k = con.slave[s]
        a = con.facets[fct, 0]
        b = con.facets[fct, 1]
        d = con.facets[fct, 2]
        wa = con.w[s, 0]
        wb = con.w[s, 1]
        wd = con.w[s, 2]
        n0 = con.nrm[s, 0]
        n1 = con.nrm[s, 1]
        n2 = con.nrm[s, 2]
        theta_f = wa * theta[a] + wb * theta[b] + wd * theta[d]
        sig = min(0.0, kn * (con.gap[s] - h0) / h0 + 0.5 * lam * (theta[k] + theta_f))
        con.sigma[s] = sig
        u0 = v[k, 0] - (wa * v[a, 0] + wb * v[b, 0] + wd * v[d, 0])
        u1 = v[k, 1] - (wa * v[a, 1] + wb * v[b, 1] + wd * v[d, 1])
        u2 = v[k, 2] - (wa * v[a, 2] + wb * v[b, 2] + wd * v[d, 2])
        # what one step can stop: a kick of dt coef / m_red (1/m_red = 1/m_k + sum_v w_v / m_v, plus the
        # rotations' share |c - x|^2 / J when the automata rotate) must not reverse the relative velocity, else
        # the explicit damper chatters (or grows beyond 2)
        inv = 1.0 / mass[k] + wa / mass[a] + wb / mass[b] + wd / mass[d]
        half = 0.5 * con.gap[s]
        cx0 = x[k, 0] - half * n0
        cx1 = x[k, 1] - half * n1
        cx2 = x[k, 2] - half * n2
        if rot is not None:
            w = rot.w
            s0, s1, s2 = _cross(w[k, 0], w[k, 1], w[k, 2], -half * n0, -half * n1, -half * n2)
            u0 += s0
            u1 += s1
            u2 += s2
            inv += half * half / rot.inertia[k]
            for q in range(3):
                j = con.facets[fct, q]
                wq = con.w[s, q]
                r0 = cx0 - x[j, 0]
                r1 = cx1 - x[j, 1]
                r2 = cx2 - x[j, 2]
                s0, s1, s2 = _cross(w[j, 0], w[j, 1], w[j, 2], r0, r1, r2)
                u0 -= wq * s0
                u1 -= wq * s1
                u2 -= wq * s2
                inv += wq * (r0 * r0 + r1 * r1 + r2 * r2) / rot.inertia[j]
        un = u0 * n0 + u1 * n1 + u2 * n2
        t0 = u0 - un * n0
        t1 = u1 - un * n1
        t2 = u2 - un * n2
        speed = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        rough = rg.value(con.rough, s) if law.rough.on else 0.0
        area = con.area[s]
        stop = 1.0 / (dt * inv)
        if law.static:
            fr0, fr1, fr2, power = _static(con, s, rot, n0, n1, n2, t0, t1, t2, speed, sig, rough, area, stop, dt,
                                           k, fct)
        else:
            dry = law.mu1 * (1.0 + rough) * min(-sig, law.sigma0)
            coef = area * (law.mu0 + dry / max(speed, law.v_reg))
            coef = min(coef, stop)
            fr0 = -coef * t0
            fr1 = -coef * t1
            fr2 = -coef * t2
            power = coef * speed * speed
        fn = -sig * area
        g0 = fn * n0 + fr0
        g1 = fn * n1 + fr1
        g2 = fn * n2 + fr2
        f[k, 0] += g0
        f[k, 1] += g1
        f[k, 2] += g2
        f[a, 0] -= wa * g0
        f[a, 1] -= wa * g1
        f[a, 2] -= wa * g2
        f[b, 0] -= wb * g0
        f[b, 1] -= wb * g1
        f[b, 2] -= wb * g2
        f[d, 0] -= wd * g0
        f[d, 1] -= wd * g1
        f[d, 2] -= wd * g2
        if rot is not None:
            mom = rot.mom
            m0, m1, m2 = _cross(-half * n0, -half * n1, -half * n2, fr0, fr1, fr2)
            mom[k, 0] += m0
            mom[k, 1] += m1
            mom[k, 2] += m2
            # the normal force at the centres leaves the couple (x_k - sum_v w_v x_v) x F_n: zero when the foot
            # lies in the facet, not when its weights were clipped (a foot up to EDGE outside); the facet's
            # automata take its opposite by their weights
            e0 = x[k, 0] - (wa * x[a, 0] + wb * x[b, 0] + wd * x[d, 0])
            e1 = x[k, 1] - (wa * x[a, 1] + wb * x[b, 1] + wd * x[d, 1])
            e2 = x[k, 2] - (wa * x[a, 2] + wb * x[b, 2] + wd * x[d, 2])
            c0, c1, c2 = _cross(e0, e1, e2, fn * n0, fn * n1, fn * n2)
            for q in range(3):
                j = con.facets[fct, q]
                wq = con.w[s, q]
                m0, m1, m2 = _cross(cx0 - x[j, 0], cx1 - x[j, 1], cx2 - x[j, 2], fr0, fr1, fr2)
                mom[j, 0] -= wq * (m0 + c0)
                mom[j, 1] -= wq * (m1 + c1)
                mom[j, 2] -= wq * (m2 + c2)
        con.fric[s, 0] = fr0
        con.fric[s, 1] = fr1
        con.fric[s, 2] = fr2
        con.speed[s] = speed
        con.power[s] = power
    _reactions(x, f, con, rot)


@njit(cache=True)
def _static(con, s, rot, n0, n1, n2, t0, t1, t2, speed, sig, rough, area, stop, dt, k, fct):
    """Static friction of slave s (Cundall-Strack): the trial stress is its spring's, carried with the contact's
    frame (the minimal rotation onto n, then the twist about n of the step's rotation by the two sides' mean
    spin: a rigid turn exactly, in steps of any size below 90 degrees), plus kt V_t dt.  Stuck, the limit is
    mu_s (1 + K) sigma_N; beyond it the contact slips at the kinetic mu1 (1 + K) sigma_N, until its slip
    velocity stops or reverses against its stress (V_t . tau <= 0; a fall of |tau| alone does not re-stick it).
    Plus the viscous mu0 V_t.  Dissipated: the stress times the slip increment, by the trapezoid rule, so the
    spring's energy and the dissipation add up to the work done.  Returns the friction force and the power."""
    law = con.law
    a0 = con.tang[s, 0]
    a1 = con.tang[s, 1]
    a2 = con.tang[s, 2]
    o0 = con.tnrm[s, 0]
    o1 = con.tnrm[s, 1]
    o2 = con.tnrm[s, 2]
    if o0 * o0 + o1 * o1 + o2 * o2 > 0.0:
        cc = o0 * n0 + o1 * n1 + o2 * n2
        if cc > 0.0:  # the minimal rotation taking the old normal onto n (Rodrigues)
            k0, k1, k2 = _cross(o0, o1, o2, n0, n1, n2)
            kv = (k0 * a0 + k1 * a1 + k2 * a2) / (1.0 + cc)
            c0, c1, c2 = _cross(k0, k1, k2, a0, a1, a2)
            a0, a1, a2 = cc * a0 + c0 + kv * k0, cc * a1 + c1 + kv * k1, cc * a2 + c2 + kv * k2
        else:  # turned by more than 90 degrees within a step: nothing to carry
            a0 = a1 = a2 = 0.0
    if rot is not None:
        # the step's rotation exp(dt W) by the two sides' mean spin W is (swing-twist decomposition) the minimal
        # rotation taking the old normal onto n (above) after a turn about the normal by
        # 2 atan2(sin(|W| dt / 2) (W / |W|) . n, cos(|W| dt / 2)): for a rigid turn the two give it exactly
        w = rot.w
        g0 = 0.5 * w[k, 0]
        g1 = 0.5 * w[k, 1]
        g2 = 0.5 * w[k, 2]
        for q in range(3):
            j = con.facets[fct, q]
            g0 += 0.5 * con.w[s, q] * w[j, 0]
            g1 += 0.5 * con.w[s, q] * w[j, 1]
            g2 += 0.5 * con.w[s, q] * w[j, 2]
        half = 0.5 * dt * math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        sinc = math.sin(half) / half if half > 0.0 else 1.0
        ang = 2.0 * math.atan2(sinc * 0.5 * dt * (g0 * n0 + g1 * n1 + g2 * n2), math.cos(half))
        if ang != 0.0:
            c0, c1, c2 = _cross(n0, n1, n2, a0, a1, a2)
            ca = math.cos(ang)
            sa = math.sin(ang)
            a0, a1, a2 = ca * a0 + sa * c0, ca * a1 + sa * c1, ca * a2 + sa * c2
    an = a0 * n0 + a1 * n1 + a2 * n2  # round-off off the plane
    a0 -= an * n0
    a1 -= an * n1
    a2 -= an * n2
    kdt = law.kt * dt
    p0 = a0 + kdt * t0
    p1 = a1 + kdt * t1
    p2 = a2 + kdt * t2
    mag = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    normal = (1.0 + rough) * min(-sig, law.sigma0)
    slipping = con.slipping[s]
    if slipping == 1 and a0 * t0 + a1 * t1 + a2 * t2 <= 0.0:
        slipping = 0
    limit = law.mu1 * normal if slipping == 1 else law.mu_s * normal
    if mag > limit:
        slipping = 1
        sc = law.mu1 * normal / mag
        b0 = sc * p0
        b1 = sc * p1
        b2 = sc * p2
    else:
        b0 = p0
        b1 = p1
        b2 = p2
    dissipated = 0.0
    if law.kt > 0.0:
        dissipated = area * (0.5 * (a0 + b0) * (p0 - b0) + 0.5 * (a1 + b1) * (p1 - b1) + 0.5 * (a2 + b2) * (p2 - b2)) \
            / law.kt
    con.tang[s, 0] = b0
    con.tang[s, 1] = b1
    con.tang[s, 2] = b2
    con.tnrm[s, 0] = n0
    con.tnrm[s, 1] = n1
    con.tnrm[s, 2] = n2
    con.slipping[s] = slipping
    vis = min(area * law.mu0, stop)
    return (-area * b0 - vis * t0, -area * b1 - vis * t1, -area * b2 - vis * t2,
            dissipated / dt + vis * speed * speed)


@njit(inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def _reactions(x, f, con, rot):
    """The held degrees of freedom's constraint reactions, -sum f over each body's (f: the pair and contact
    forces of the step, before the loads), and their moment about the origin: sum x x (-f) over the held
    translations, -sum M over the held rotations."""
    for g in range(2):
        for c in range(3):
            con.reaction[g, c] = 0.0
            con.moment[g, c] = 0.0
    for i in range(con.held.shape[0]):
        for c in range(3):
            g = con.held[i, c]
            if g > 0:
                r = -f[i, c]
                con.reaction[g - 1, c] += r
                # x_i x (r e_c)
                c1 = (c + 1) % 3
                c2 = (c + 2) % 3
                con.moment[g - 1, c1] += x[i, c2] * r
                con.moment[g - 1, c2] -= x[i, c1] * r
            if rot is not None:
                g = con.held_rot[i, c]
                if g > 0:
                    con.moment[g - 1, c] -= rot.mom[i, c]


@njit(cache=True)
def after_step(con, dt):
    """Time integration of the contacts over one step: friction heat into the automata (half to each body), the
    roughness advanced, the reactions into their impulses; returns the energy friction dissipated (J)."""
    for g in range(2):
        for c in range(3):
            con.impulse[g, c] += con.reaction[g, c] * dt
            con.angular_impulse[g, c] += con.moment[g, c] * dt
    total = 0.0
    for s in range(con.slave.shape[0]):
        fct = con.facet[s]
        if fct < 0:
            continue
        q = con.power[s] * dt
        total += q
        con.dissipated[s] += q
        con.heat[con.slave[s]] += 0.5 * q
        for v in range(3):
            con.heat[con.facets[fct, v]] += 0.5 * con.w[s, v] * q
        if con.law.rough.on:
            rg.advance(con.rough, con.law.rough, s, con.speed[s] * dt)
    return total


@njit(cache=True)
def energy(con, kn):
    """Elastic energy of the closed contacts: sum kn S (h - h0)^2 / (2 h0), and with static friction the
    tangential springs' sum S |tau|^2 / (2 kt)."""
    u = 0.0
    spring = 0.0
    for s in range(con.slave.shape[0]):
        if con.facet[s] >= 0:
            dh = con.gap[s] - con.law.h0
            u += 0.5 * con.area[s] * dh * dh / con.law.h0
            if con.law.static and con.law.kt > 0.0:
                tt = con.tang[s, 0] ** 2 + con.tang[s, 1] ** 2 + con.tang[s, 2] ** 2
                spring += 0.5 * con.area[s] * tt / con.law.kt
    return kn * u + spring


@njit(cache=True)
def resultants(con):
    """(friction resistance along the sliding direction, normal force along the contact axis, closed
    contacts) on body 2: sum -F_R . e_dir, sum -sigma_c S n . e_axis."""
    fr = 0.0
    fn = 0.0
    count = 0
    for s in range(con.slave.shape[0]):
        if con.facet[s] >= 0:
            fr -= con.fric[s, con.law.direction]
            fn -= con.sigma[s] * con.area[s] * con.nrm[s, con.law.axis]
            count += 1
    return fr, fn, count
