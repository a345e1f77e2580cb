"""The parameters of the continuum solvers, declared apart from them so that the command line checks a
study's or a run's parameters without importing FiPy or scikit-fem."""

from __future__ import annotations

from pcverify.scene import Param

FIPY_HEAT: tuple[Param, ...] = (
    Param("patch", "cut", "", "patch constraint: cut (fixed cells + Shortley-Weller faces), volume-fraction "
          "weighted penalty, or staircase", choices=("cut", "fraction", "staircase"), kind=str),
    Param("scheme", "crank-nicolson", "", "time scheme of transient scenes",
          choices=("implicit-euler", "crank-nicolson"), kind=str),
    Param("rannacher_steps", 4, "", "implicit-Euler half steps that start Crank-Nicolson (even)",
          low=0, high=100, kind=int),
    Param("linear_solver", "auto", "", "auto: direct (splu) up to amg_threshold free unknowns, else "
          "pyamg smoothed-aggregation CG", choices=("auto", "direct", "amg"), kind=str),
    Param("amg_threshold", 10000, "", "free unknowns above which 'auto' uses AMG", low=0, high=1e9, kind=int),
    Param("rtol", 1e-10, "", "relative residual of AMG-CG (checked on the true residual)",
          low=0.0, high=1e-3, low_open=True),
    Param("penalty", 1e8, "", "penalty factor: B = penalty * k / h^2 for fixed cells", low=1e3, high=1e14),
    Param("max_steps", 1_000_000, "", "largest number of time steps of a transient (t_end / dt)", low=1,
          high=1e10, kind=int),
)

SKFEM_HEAT: tuple[Param, ...] = (
    Param("scheme", "crank-nicolson", "", "time integration of transient scenes",
          choices=("implicit-euler", "crank-nicolson"), kind=str),
    Param("rannacher_steps", 4, "", "implicit-Euler half steps that start Crank-Nicolson (even; 0 = plain CN)",
          low=0, high=1000, kind=int),
    Param("patch", "conforming", "", "patch constraint: warped conforming sphere or staircase of nodes",
          choices=("conforming", "staircase"), kind=str),
    Param("linear_solver", "auto", "", "direct (SuperLU), amg (pyamg SA-preconditioned CG) or auto",
          choices=("auto", "direct", "amg"), kind=str),
    Param("cg_rtol", 1e-11, "", "relative residual tolerance of CG", low=0.0, high=1e-3, low_open=True),
    Param("max_steps", 1_000_000, "", "largest number of time steps of a transient (t_end / dt)", low=1, high=1e10,
          kind=int),
    Param("direct_max_unknowns", 10000, "", "auto: direct solver up to this many free nodes, AMG-CG above",
          low=1, high=1e9, kind=int),
)

SKFEM_ELASTIC: tuple[Param, ...] = (
    Param("element", "q2", "", "Q1 (trilinear) or Q2 (triquadratic) hexahedra", choices=("q1", "q2"), kind=str),
    Param("linear_solver", "auto", "", "direct (SuperLU), amg (pyamg SA-preconditioned CG) or auto",
          choices=("auto", "direct", "amg"), kind=str),
    Param("cg_rtol", 1e-11, "", "relative residual tolerance of CG", low=0.0, high=1e-3, low_open=True),
    Param("direct_max_unknowns", 10000, "", "auto, static: direct solver up to this many unknowns, AMG-CG above",
          low=1, high=1e9, kind=int),
    Param("modal_direct_max_unknowns", 60000, "", "auto, modal: direct shift-invert up to this many unknowns",
          low=1, high=1e9, kind=int),
)
