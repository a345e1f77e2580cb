"""The MCA solver's model notes: where it departs from the MCA paper (Psakhie et al., PHYSICS.md §4) or makes a
choice the paper leaves open, each with its reason and, where it matters, a measured number.  `pcverify solvers`
and every report that runs the solver show them; references/physics.md carries the same list."""

from __future__ import annotations

MODEL_NOTES: tuple[str, ...] = (
    "Many-body transfer without the paper's delay (section 3): the paper's equations (4)-(5) let the overlap of "
    "pairs ik and jl act on pair ij after a delay set by the automata's size and the sound speeds.  Here an "
    "automaton's volume strain enters its pairs' stresses in the same force evaluation, so the transfer takes one "
    "time step: dt = 0.19 a / c_p at the default cfl 0.5 (the same at every n; c_p = sqrt(M / rho) = 6090 m/s for "
    "duralumin), a sub-step the explicit scheme cannot resolve.  The scenes are quasi-static or elastic waves "
    "of at least four spacings; shock waves, which the paper says need a treatment of their own, are not among "
    "them.",
    "Contact normal law (eq. 10): the contact is the compressive half of the bonded pair law written for the foot "
    "point, sigma = kn (h - h0) / h0 + lam (theta_k + sum w theta) / 2, not eq. 10's E (h - h0) / h0; and h0 is "
    "the rest distance d of face neighbours on the cubic lattice, not sqrt(3) R (the height of a disc resting in "
    "the hollow of two discs in 2-D close packing).  Under uniaxial stress the two laws agree (E eps); under "
    "confined compression the pair law gives M = K + 4G/3 = 103.7 GPa against eq. 10's E = 70 GPa (duralumin), "
    "so eq. 10 would make every interface of a confined body a compliant layer.  With the pair law a stack "
    "compressed across a flat interface is exactly its bonded lattice (the contact-friction study's compression "
    "group).",
    "Micro-roughness K_mu (eq. 18, section 7): the regularity parameter d_m is taken as the mean half-period of "
    "the sinusoid fragments (the paper says only that the fragments' lengths correlate with d), each fragment "
    "one positive half-wave, so K_av = (2 / pi)(A1 + A2) / A.  The paper makes K_av grow and the relative "
    "amplitude fall with the automaton size R and with the contact area S, but gives no law: here d, the "
    "amplitudes and K_av are the user's parameters and do not change with R (the resolution) or S; a study that "
    "refines the lattice keeps the same K_mu process.",
    "Sliding coordinate of K_mu (eq. 18): x advances by |V_t| dt, the distance slid (V_t is a vector in 3-D), "
    "not by a signed V_t dt: a contact that reverses its sliding continues the profile instead of retracing it.  "
    "Every scene slides one way, where the two agree.",
)
