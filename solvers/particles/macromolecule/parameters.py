"""The macromolecule solver's parameters, declared apart from the solver so that the command line checks
them without importing numba."""

from __future__ import annotations

from pcverify.scene import Param

DEFAULT_DAMPING_RATIO = 0.01

PARAMETERS: tuple[Param, ...] = (
    Param("f_top", 50.0, "Hz", "target highest natural frequency of the held lattice; sets A", low=1e-3, high=1e5),
    Param("stiffness", None, "N", "force scale A (overrides f_top)", low=0.0, high=1e12, low_open=True, optional=True),
    Param("p", 2.0, "", "envelope exponent of (a/r)^p", low=0.0, high=12.0),
    Param("s", 0.9, "", "STEP start 2 s a (STEP ends at 2a)", low=0.5, high=0.99),
    Param("unstable_fraction", 0.5, "", "position of each unstable root inside its gap (0.5: midpoint)",
          low=0.05, high=0.95),
    Param("delta", None, "N s/m", "radial pair damping (the paper's parameter); excludes damping_ratio", low=0.0,
          high=1e6, optional=True),
    Param("damping_ratio", None, "", f"damping ratio of the top mode (damped modal problem); default "
          f"{DEFAULT_DAMPING_RATIO} when delta is not given", low=0.0, high=0.5, optional=True),
    Param("drive_amplitude", 0.05, "a", "D: stroke of the red pair (or face drive amplitude); below 1e-9 a the "
          "stroke per step is lost in the rounding of the positions", low=1e-9, high=0.1),
    Param("drive_frequency", 50.0, "Hz", "f of the drive", low=0.0, high=1e5, low_open=True),
    Param("drive_sharing", "free-centre", "", "how the red pair's stroke is shared", choices=("free-centre",
          "symmetric"), kind=str),
    Param("t_end", 15.0, "s", "end of the run and of the averaging window", low=0.0, high=1e5, low_open=True),
    Param("t_start", 0.0, "s", "start of the averaging window", low=0.0, high=1e5),
    Param("safety", 0.05, "", "dt = safety * 2 / omega_max; default 0.05, not 0.1: at 0.1 the driven lattice's "
          "energy balance misses 1e-3 from n = 4 on (2.0-3.1e-3, velocity Verlet's dt^2 error on the anharmonic "
          "force; kernel.py), at 0.05 it closes to <= 8e-4 for n = 2..11", low=0.0, high=1.0, low_open=True),
    Param("dt", None, "s", "time step (overrides safety; must be below the stability limit)", low=0.0, high=1.0,
          low_open=True, optional=True),
    Param("pairs_at_2a", "keep", "", "keep or drop the pairs resting at exactly 2a", choices=("keep", "drop"),
          kind=str),
    Param("face_drive_direction", "y", "", "bar-heat-faces, hot_face=driven: direction of the face drive (z: "
          "normal to the face, longitudinal)", choices=("x", "y", "z"), kind=str),
    Param("hot_face", "langevin", "", "bar-heat-faces: z=0 face thermostatted or kinematically driven",
          choices=("langevin", "driven"), kind=str),
    Param("far_face", "absorbing", "", "bar-heat-faces: z=L face viscous (0 K bath) or frozen",
          choices=("absorbing", "frozen"), kind=str),
    Param("face_gamma", None, "1/s", "bath friction rate of the faces (default omega_max / 2)", low=0.0, high=1e9,
          low_open=True, optional=True),
    Param("seed", 0, "", "seed of face phases, Langevin noise and the initial perturbation", low=0, high=2**31 - 1,
          kind=int),
    Param("perturbation", 0.0, "a 2 pi f_top", "random initial velocities of the free particles (normal, seeded by "
          "seed), in units of a 2 pi f_top: replicas of a run whose trajectory is chaotic (defect regime) differ by "
          "it, so their spread measures how much of a value is the arithmetic's", low=0.0, high=1e-3),
    Param("stop_tol", 0.02, "", "stationarity stop: the averaging window grows by doubling from a sixteenth of "
          "[t_start, t_end] and the run ends at the first window whose halves agree within this (every free "
          "particle's mean hotness, relative to the hottest free one); the window mean is then within about half "
          "of it of its long-time value (a start-up transient decays as 1/t in it); 0 runs to t_end", low=0.0,
          high=1.0),
    Param("stationarity_tol", 0.1, "", "non-stationary if the hotness of a free particle changes by more than this "
          "(relative to the hottest free one) between the halves of the window", low=0.0, high=10.0, low_open=True),
    Param("blowup_factor", 10.0, "", "unstable if the kinetic energy exceeds this times the energy supplied",
          low=1.0, high=1e12),
    Param("contact_fraction", 0.5, "a", "unlisted particles closer than this break the pair list", low=0.0, high=1.0,
          low_open=True),
    Param("max_steps", 20_000_000, "", "largest number of time steps a run may take (t_end / dt)", low=1, high=1e10,
          kind=int),
    Param("dt_check", False, "", "rerun at dt/2 and report the change in relative hotness", kind=bool),
    Param("start", "rest", "", "initial state: at rest on the lattice (the paper), or at rest displaced along the "
          "held lattice's top mode by start_amplitude (a verification run: its mean kinetic energy and its decay "
          "have closed forms, summary top_mode_*; drive it far below f_top)", choices=("rest", "top-mode"), kind=str),
    Param("start_amplitude", 1e-5, "a", "start = top-mode: the largest particle displacement (small: the lattice "
          "is linear to first order in it)", low=0.0, high=1e-2, low_open=True),
    Param("setup_check", False, "", "recompute omega_max from the Hessian of the force model as built and report "
          "f_top_check_hz and dt_safety_check = dt omega_max / 2", kind=bool),
    Param("stop_check", False, "", "rerun without the stationarity stop and report the largest change in relative "
          "hotness of a free particle (stop_deviation)", kind=bool),
    Param("dt_guard", True, "", "refuse a dt above the stability limit of the linearised scheme (or leaving fewer than "
          "100 steps in the averaging window); false runs it, its checks report a blow-up (the stability probe)",
          kind=bool),
)
