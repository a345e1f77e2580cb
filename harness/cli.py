"""Command line `pcverify`: the parser, and the table of the modules that run each command.

This module parses and checks the arguments and imports nothing a command needs to run, so that help, `scenes`
and a one-line input error answer before the numerical libraries (seconds of CPU) would have loaded.  COMMANDS
names each command's module of `run` or `report` as "module:function", imported once the arguments are checked
(`check_input` first checks what needs no numerical library: a scene, solver or study name, an option that
needs one study).  Every bad input ends in one line `pcverify: error: ...` naming the parameter and the
allowed range, with exit code 2; never a traceback (unless --debug).
"""

from __future__ import annotations

import sys
from pathlib import Path

from pcverify.harness.run.interrupt import exit_on_sigterm_at_start_up

# as the command (not imported by a test), a SIGTERM from here on is the one "terminated" line and exit 143,
# never a silent death
if __name__ == "__main__" or Path(sys.argv[0] if sys.argv else "").name == "pcverify":
    exit_on_sigterm_at_start_up()

import argparse
import contextlib
import importlib
import os
import signal
from collections.abc import Callable

from pcverify import __version__
from pcverify.harness.run.interrupt import TERMINATED, received, sigterm_interrupts
from pcverify.harness.run.limits import DEFAULT_MUTANT_TIME_LIMIT, DEFAULT_TIME_LIMIT, MAX_TIME_LIMIT
from pcverify.harness.study.catalogue import get_spec
from pcverify.harness.study.schema import MAX_CELLS
from pcverify.harness.study.settings import split_settings
from pcverify.harness.study.shipped import study_path
from pcverify.scene import SceneError, shown
from pcverify.solvers.registry import SolverUnavailable, check_solver_name, shipped_parameters

COMMANDS = {  # command -> "module:function" that runs it, given the parsed arguments; returns the exit code
    "scenes": "pcverify.harness.report.listings:list_scenes",
    "solvers": "pcverify.harness.report.listings:list_solvers",
    "run": "pcverify.harness.run.one_cell:run_one_cell",
    "study": "pcverify.harness.report.studies:run_studies",
    "verdict": "pcverify.harness.report.claim_verdict:judge_claim",
    "mutate": "pcverify.harness.report.mutation_testing:run_mutants",
    "sensitivity": "pcverify.harness.report.sensitivity_analysis:run_sensitivity",
    "report": "pcverify.harness.report.rebuild:rebuild_reports",
    "bench": "pcverify.harness.report.benchmarks:run_benchmarks",
}

EPILOG = """\
examples:
  pcverify scenes                                   list the scenes and their parameters
  pcverify scenes stick-slip                        one scene: its reference and its family's summary scalars
  pcverify solvers                                  list the solvers and their parameters
  pcverify run bar-heat-faces --solver skfem --n 4 --json
  pcverify run bar-heat-patch --solver fipy --n 3 --refine 4 --set rho=0.002
  pcverify run bar-heat-faces --solver skfem --set mode=transient --set scheme=crank-nicolson
  pcverify study default                            run the default studies, write reports/
  pcverify study default --dry-run                  show what is cached and what would run
  pcverify study stability --group limit-mca-heat   run one group of a study (from the cache where it can)
  pcverify study my.toml --strict                   exit 1 unless every verdict passes (a CI gate)
  pcverify verdict heat-particles mca-steady-line   judge one claim, print its value (from the cache)
  pcverify mutate my.toml --strict                  run the claims on the study's mutants: exit 1 unless all
                                                    are killed
  pcverify sensitivity manufactured                 which claim sees which input (scene numbers, solver
                                                    parameters scaled by 1 %): the matrix and the blind spots
  pcverify report                                   rebuild reports/index.html from the cache
  pcverify bench                                    benchmarks, saved and compared with the previous run

--set KEY=VALUE goes to the scene if the scene has KEY, else to the solver;
write scene.KEY or solver.KEY when both have it.
"""


class OneLineParser(argparse.ArgumentParser):
    """argparse with usage errors as one line `pcverify: error: ...` (exit 2), like every other error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, error_line(message) + "\n")


WORD_LIMIT = 240  # characters of one word of an error line: a path fits, a hostile 100 kB name does not


def error_line(message: str) -> str:
    """`pcverify: error: ...` on one line, every word longer than WORD_LIMIT shortened to its start and length."""
    words = [w if len(w) <= WORD_LIMIT else f"{w[:WORD_LIMIT - 20]}...({len(w)} characters){w[-1] * (w[-1] in ';,:')}"
             for w in message.split()]
    return "pcverify: error: " + " ".join(words)


def report_error(message: str) -> None:
    """Print an error line on stderr on a line of its own: progress bars still open are closed first (tqdm is
    loaded by the commands that draw a bar, and by plugins; where it is not loaded, no bar is open)."""
    bars = getattr(sys.modules.get("tqdm"), "tqdm", None)
    for bar in list(getattr(bars, "_instances", ())):
        bar.close()
    print(error_line(message), file=sys.stderr)


def int_in(name: str, low: int, high: int) -> Callable[[str], int]:
    """argparse type: an integer in [low, high], else a one-line error naming it and the range."""

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not low <= value <= high:
            shown = text if len(text) <= 40 else text[:37] + "..."
            shown = shown if shown.strip() and shown.isprintable() else repr(shown)
            raise argparse.ArgumentTypeError(f"{name}={shown} is not valid; allowed: integer in [{low}, {high}]")
        return value

    return convert


def real_in(name: str, low: float, high: float, what: str = "number") -> Callable[[str], float]:
    """argparse type: a number (`what`: seconds, ...) in (low, high], else a one-line error naming it and the
    range."""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = None
        if value is None or not low < value <= high:
            raise argparse.ArgumentTypeError(f"{name}={shown(text)} is not valid; allowed: {what} in ({low:g}, "
                                             f"{high:g}]")
        return value

    return convert


def seconds_in(name: str, low: float, high: float) -> Callable[[str], float]:
    """argparse type: a number of seconds in (low, high] (`real_in`)."""
    return real_in(name, low, high, "seconds")


TIME_LIMIT_HELP = (f"kill a computed cell after SECONDS, failing it with that reason (default {DEFAULT_TIME_LIMIT:g}: "
                   "six times the ten minutes the work limits allow a cell)")


def add_limits(p: argparse.ArgumentParser, allow_large: str) -> None:
    """The options every command that computes cells has: --allow-large (what it allows) and --time-limit."""
    p.add_argument("--allow-large", action="store_true", help=allow_large)
    p.add_argument("--time-limit", type=seconds_in("time-limit", 0, MAX_TIME_LIMIT), default=DEFAULT_TIME_LIMIT,
                   metavar="SECONDS", help=TIME_LIMIT_HELP)


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command, its options and their ranges (checked as they are parsed)."""
    parser = OneLineParser(
        prog="pcverify",
        description="Verify particle methods (macromolecule, MCA) against continuum solvers (FiPy, scikit-fem) "
        "and analytic solutions: run one scene, run studies, write reports.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"pcverify {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("scenes", help="list the scene catalogue with parameters (name, default, range, unit)")
    p.add_argument("scene", nargs="?", help="one scene, with its reference and its family's summary scalars")
    p.add_argument("--json", action="store_true", help="machine-readable output")

    p = sub.add_parser("solvers", help="list the solvers with their parameters")
    p.add_argument("--json", action="store_true", help="machine-readable output")

    p = sub.add_parser("run", help="solve one scene with one solver and print the solution",
                       description="Solve SCENE with --solver at lattice resolution n (one spacing a = width / (n-1) "
                       "on every axis: n x n x (3n-2) nodes on the paper's bar).")
    p.add_argument("scene", help="scene name (see `pcverify scenes`)")
    p.add_argument("--solver", required=True, help="solver name (see `pcverify solvers`) or module:Class of a solver "
                   "that is not installed as a plugin")
    p.add_argument("--n", type=int_in("n", 2, 1000), default=4,
                   help="lattice resolution n >= 2 (default 4: 160 nodes)")
    p.add_argument("--refine", type=int_in("refine", 1, 1000), default=1,
                   help="grid refinement factor of continuum solvers (default 1)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene or solver parameter (repeatable)")
    add_limits(p, "run a solve beyond the work and memory limits")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")

    p = sub.add_parser("study", help="run a study (a grid of scenes x solvers x resolutions) and write reports/",
                       description="Run the named study (or a TOML file), cache every cell, write tables and plots.")
    p.add_argument("name", help="study name (`default` runs all default studies) or a path to a .toml file")
    p.add_argument("--dry-run", action="store_true", help="list what is cached and what would run; run nothing")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1,
                   help="parallel cells on local cores (default 1)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="hand the cells to a Dask cluster (e.g. tcp://host:8786; needs pcverify[dask])")
    add_limits(p, f"run a study of more than {MAX_CELLS} cells, or cells beyond the work and memory limits")
    p.add_argument("--rerun", nargs="*", default=None, metavar="SOLVER",
                   help="recompute cached cells: all of them, or those of the named solvers (put it last)")
    p.add_argument("--json", action="store_true", help="print a JSON summary per study with its verdicts (the records "
                   "of verdicts.json; with --dry-run: the plan of every cell), nothing else on stdout")
    p.add_argument("--group", action="append", metavar="ID", help="run only this group of the study (repeatable; "
                   "the groups it reads tables from are included)")
    p.add_argument("--strict", action="store_true", help="exit 1 when any verdict is not a pass (fail, inconclusive or "
                   "not applicable), listing each with why and its reproducing command on stderr (a CI gate)")

    p = sub.add_parser("verdict", help="judge one claim of a study and print its value, target, error, uncertainty",
                       description="Run the groups a claim reads (cached cells are read back), judge the claim and "
                       "print each verdict: the command printed beside every verdict in the report.  Exit 1 unless "
                       "every verdict printed is a pass.")
    p.add_argument("study", help="study name or a path to a .toml file")
    p.add_argument("claim", help="claim id (see the study file)")
    p.add_argument("--case", default=None, help="one case of the claim, as the report writes it (e.g. n=4)")
    p.add_argument("--out", default="reports", help="where the study's cache is (default reports/: reports/cache)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1, help="parallel cells on local cores (default 1)")
    add_limits(p, "run cells beyond the work and memory limits")
    p.add_argument("--json", action="store_true", help="print the verdict records as JSON")

    p = sub.add_parser("mutate", help="run a study's claims on deliberate defects of the code: which claims catch "
                       "which mutant", description="Run the study (the baseline), then each of its mutants ([[mutant]] "
                       "tables, STUDY.mutants.toml beside it, plugins' pcverify.mutants entry points) in a process of "
                       "its own on the mutated code; a mutant is killed when a claim that passes on the original does "
                       "not pass on it.  Writes OUT/STUDY/mutants.json, the kill matrix and a section of the report.")
    p.add_argument("name", help="study name (`default`: every shipped study with mutants) or a path to a .toml file")
    p.add_argument("--mutant", action="append", metavar="NAME", help="run only this mutant (repeatable)")
    p.add_argument("--group", action="append", metavar="ID", help="judge only the claims of this group (repeatable; "
                   "the groups it reads tables from are included); without it, every group a claim reads runs")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1,
                   help="mutants run at once, each running its study on one worker, and the baseline's cells run "
                   "at once (default 1)")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache); mutants keep theirs under "
                   "CACHE/mutants/")
    add_limits(p, f"run a study of more than {MAX_CELLS} cells, or cells beyond the work and memory limits")
    p.add_argument("--mutant-time-limit", type=seconds_in("mutant-time-limit", 0, MAX_TIME_LIMIT),
                   default=DEFAULT_MUTANT_TIME_LIMIT, metavar="SECONDS", help="stop a mutant's whole run after SECONDS "
                   f"(status crashed; its finished cells are kept; default {DEFAULT_MUTANT_TIME_LIMIT:g})")
    p.add_argument("--json", action="store_true", help="print mutants.json of each study (a list), nothing else on "
                   "stdout")
    p.add_argument("--strict", action="store_true", help="exit 1 when a mutant survives, is invalid, crashed or "
                   "was killed only incidentally (a CI gate)")

    p = sub.add_parser("sensitivity", help="which claim sees which model input: each input scaled by 1 + step, "
                       "the claims judged again", description="Run the study (the baseline), then scale each model "
                       "input its cells hand their solvers (the scene's numbers: box, material constants, held values, "
                       "loads; the solvers' number parameters) by 1 + STEP in every cell that has it, in the solver "
                       "only, and judge the claims again.  Writes OUT/STUDY/sensitivity.json, the matrix inputs x "
                       "claims and a section of the report listing the blind spots (inputs no claim sees).")
    p.add_argument("name", help="study name or a path to a .toml file")
    p.add_argument("--input", action="append", metavar="NAME", help="perturb only this input, OWNER:PATH as the "
                   "matrix names it, or a glob (e.g. 'mca:*', '*:material.*'; repeatable)")
    p.add_argument("--step", type=real_in("step", 0, 0.5), default=0.01,
                   help="relative step (default 0.01; 1 - step where 1 + step leaves an input's range)")
    p.add_argument("--jobs", type=int_in("jobs", 1, 256), default=1, help="parallel cells on local cores (default 1)")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--cache", default=None, help="cache folder (default OUT/cache); perturbed cells are cached "
                   "under CACHE/sensitivity/STUDY/")
    add_limits(p, f"run a study of more than {MAX_CELLS} cells, or cells beyond the work and memory limits")
    p.add_argument("--json", action="store_true", help="print sensitivity.json, nothing else on stdout")
    p.add_argument("--strict", action="store_true",
                   help="exit 1 when an input is a blind spot or a claim is out of reach (a CI gate)")

    p = sub.add_parser("bench", help="run the benchmarks, save them, compare with the previous saved run")
    p.add_argument("--tests", default="tests/bench", help="benchmark folder (default tests/bench)")
    p.add_argument("--storage", default="reports/benchmarks", help="where runs are saved (default reports/benchmarks)")
    p.add_argument("--fail-percent", type=float, default=25.0, help="regression of the mean that fails (default 25)")

    p = sub.add_parser("report", help="rebuild the tables and reports/index.html from cached results")
    p.add_argument("--out", default="reports", help="output folder (default reports/)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    return parser


def check_input(args: argparse.Namespace) -> None:
    """The checks of a command's input that need no numerical library, before its module is imported: each
    raises the one-line error the command would give later (a scene, solver or study name that is unknown, an
    option that needs one study given with `default`, a benchmark folder that is not there)."""
    if args.command == "run":
        spec = get_spec(args.scene)
        check_solver_name(args.solver)
        solver_params = shipped_parameters(args.solver)
        if solver_params is not None:  # a plugin's parameters are checked when its module is imported
            split_settings(args.set or [], spec.parameters, solver_params)
    elif args.command == "verdict":
        study_path(args.study)
    elif args.command == "sensitivity":
        study_path(args.name)
    elif args.command in ("study", "mutate") and args.name != "default":
        study_path(args.name)
    elif args.command in ("study", "mutate"):
        for option in ("--group", "--mutant")[: 1 if args.command == "study" else 2]:
            if getattr(args, option[2:]):
                raise SceneError(f"{option} needs one study; allowed: a study name or a .toml file, not default")
    if args.command == "bench" and not Path(args.tests).exists():  # the benchmarks come with a checkout only
        raise SceneError(f"bench runs the benchmarks of a checkout of the project (its tests/bench), which an "
                         f"installed pcverify does not have; --tests {args.tests}: no such folder in {Path.cwd()}; "
                         "allowed: run it in a checkout of the project, or --tests PATH (a folder of "
                         "pytest-benchmark tests)")


def command(name: str) -> Callable[[argparse.Namespace], int]:
    """The function that runs command `name` (COMMANDS), its module imported now."""
    module, _, function = COMMANDS[name].partition(":")
    return getattr(importlib.import_module(module), function)


def _exit_site(exc: BaseException) -> str:
    """Where sys.exit was called: the innermost frame of its traceback (file:line)."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    return f"{tb.tb_frame.f_code.co_filename}:{tb.tb_lineno}" if tb is not None else "an unknown place"


def main(argv: list[str] | None = None) -> int:
    """`pcverify ARGS`: parse, check, run the command; its exit code (2 and one line for bad input)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage errors were printed as one line by OneLineParser; --help exits 0
        if exc.code == 2:
            return 2
        raise
    if not args.command:
        parser.print_help()
        return 0
    try:
        with sigterm_interrupts():  # SIGTERM anywhere in a command: KeyboardInterrupt, the "terminated" line below
            with contextlib.redirect_stdout(sys.stderr):  # a plugin's prints, on import of its scene
                check_input(args)
            code = command(args.command)(args)
            sys.stdout.flush()  # here, not at exit: a reader gone by now is the BrokenPipeError below, not a traceback
            return code
    except (SceneError, SolverUnavailable, FileNotFoundError) as exc:
        if args.debug:
            raise
        report_error(str(exc))
        return 2
    except SystemExit as exc:  # sys.exit inside the command: a plugin's code (ours return their exit codes)
        if args.debug:
            raise
        report_error(f"the command was ended by sys.exit({exc.code!r}) in {_exit_site(exc)}, before it finished; "
                     "allowed: a plugin that raises an exception or returns")
        return 2
    except BrokenPipeError:  # the reader of stdout has gone (`pcverify scenes | head`): not an error of ours
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit's flush
        return 141  # as a shell reports a process ended by SIGPIPE
    except OSError as exc:  # a read-only or full output folder, a path that is a file, ...
        if args.debug:
            raise
        where = f"{exc.strerror}: {exc.filename}" if exc.filename and exc.strerror else str(exc)
        hint = "; finished cells are kept in the cache, rerun to resume" if args.command == "study" else ""
        report_error(f"{where}{hint if 'rerun' not in where else ''}")
        return 2
    except KeyboardInterrupt:
        if received() == signal.SIGTERM:
            print("\npcverify: terminated (finished cells are kept in the cache)", file=sys.stderr)
            return TERMINATED
        print("\npcverify: interrupted (finished cells are kept in the cache)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
