"""The study file's schema: every table and key of a study file declared once, and the one walk that checks
a document against a declaration.

A `Field` declares one key (its kind, range or choices, whether it is required, its default and
description); a `Table` declares the keys of one kind of table.  `STUDY` is the top level, and its lists of
tables are `TABLES` ([[scene]], [[group]], [[claim]], [[calibration]] with their nested tables, [[mutant]]): a new kind
of table is one `Table` added there.  `check` walks a value against a declaration and raises, at the first
problem, one SceneError line in one dialect that names where (the file, the table, its number from 1 and
its id or name), the field, the value and what is allowed:

    study file s.toml: group[2] (g): n=1 is not valid; allowed: integer in [2, 1000]

Registries above this module (the analyses with their group options, the group figures) are passed to
`check` by name.  Checks that need other objects (a solver's parameters, a scene name, a calibration's
overlap guard) run after the walk, in the modules that own those objects.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from pcverify.scene import EXTENT_RANGE, FACES, MATERIALS, MODES, Box, Conduction, Param, SceneError, is_real, shown

Registries = Mapping[str, Mapping[str, Any]]


@dataclass(frozen=True)
class Field:
    """One key of a table.  kind: int, real (finite, not a bool), bool, text (a `pattern` to match whole),
    scalar (text, number or true/false), table ({ key = value }, each
    value a `values` field if given), record (a nested `table`), tables (a list of `table` rows) or any
    (the first of `alternatives` whose type fits).  shape: "" (one value), "list", or "value or list" (a
    string is one value).  `registry`: the choices are the names of that registry, given to `check`.  `hint`
    says what is allowed where the kind does not (a pattern's meaning, the name of what)."""

    name: str
    kind: str
    description: str = ""
    hint: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[Any, ...] = ()
    registry: str = ""
    pattern: str = ""
    required: bool = False
    default: Any = None
    shape: str = ""
    min_items: int = 1
    max_items: int | None = None
    values: Field | None = None
    table: Table | None = None
    alternatives: tuple[Field, ...] = ()
    unique: bool = False  # one value per row of the list of tables it is in (with the table's default_key)

    def allowed(self, registries: Registries) -> str:
        """What a valid value is, in words (the end of every error line about this field)."""
        if self.alternatives:
            return " or ".join(a.allowed(registries) for a in self.alternatives)
        choices = tuple(registries[self.registry]) if self.registry else self.choices
        if self.kind == "tables":
            rows = f"{self.table.title} tables" if self.table.title.startswith("[[") else \
                f"tables {{ {', '.join(f.name for f in self.table.fields)} }}"
            return f"{'one or more' if self.min_items else 'a list of'} {rows}"
        if self.kind == "record":
            return f"a table {{ {', '.join(f.name for f in self.table.fields)} }}"
        if self.kind == "table":
            return "a table { key = value, ... }" + (f" of {self.values.allowed(registries)}" if self.values else "")
        if choices:
            one = "one of " + ", ".join(map(str, choices))
        elif self.kind in ("int", "real"):
            if self.low is None and self.high is None:
                one = "integer" if self.kind == "int" else "number"
            elif self.kind == "int":  # whole numbers, never in float notation (2147483647, not 2.14748e+09)
                one = f"integer in [{self.low if self.low is not None else '-inf'}, " \
                      f"{self.high if self.high is not None else 'inf'}]"
            else:
                one = Param(self.name, None, low=self.low, high=self.high, low_open=self.low_open).allowed()
        else:
            one = self.hint or {"bool": "true/false", "scalar": "a value"}.get(self.kind, self.kind)
        if self.shape == "list" and self.min_items == self.max_items:
            return f"a list of {self.min_items} values, each {one}"
        if self.shape == "list":
            return f"a {'non-empty ' if self.min_items else ''}list of {one}"
        return f"{one}, or a {'non-empty ' if self.min_items else ''}list of them" if self.shape else one

    def fits(self, value: Any, registries: Registries) -> bool:
        """Whether one value (an item of a list shape) is of this field's kind, in its range and choices."""
        ok = TYPES[self.kind](value) and (self.kind != "text" or re.fullmatch(self.pattern or "(?s).*", value))
        if ok and self.kind in ("int", "real"):
            ok = (self.low is None or value > self.low or (value == self.low and not self.low_open)) and (
                self.high is None or value <= self.high)
        choices = registries[self.registry] if self.registry else self.choices
        return bool(ok) and (not choices or value in choices)

    def type_fits(self, value: Any) -> bool:
        """Whether the value has this field's type at all (how `alternatives` pick the one that applies)."""
        if self.shape:
            return isinstance(value, list) or (self.shape == "value or list" and not isinstance(value, dict))
        return TYPES[self.kind](value)


TYPES = {"int": lambda v: isinstance(v, int) and not isinstance(v, bool), "real": is_real,
         "bool": lambda v: isinstance(v, bool), "text": lambda v: isinstance(v, str),
         "scalar": lambda v: isinstance(v, (str, int, float, bool)), "table": lambda v: isinstance(v, dict),
         "record": lambda v: isinstance(v, dict), "tables": lambda v: isinstance(v, list)}


@dataclass(frozen=True)
class Table:
    """The keys of one kind of table.  `key` names a row in messages (id or name; `default_key` formatted with
    the row's number when it has none); `variant` is a field whose registry maps each value to more fields
    (a group's analysis and its options); `one_of` are keys of which exactly one must be given."""

    title: str
    fields: tuple[Field, ...]
    key: str = ""
    default_key: str = ""
    variant: str = ""
    one_of: tuple[str, ...] = ()

    def field(self, name: str) -> Field:
        return next(f for f in self.fields if f.name == name)


def check(value: Any, table: Table, where: str, registries: Registries | None = None) -> dict[str, Any]:
    """Check `value` (a parsed TOML table) against `table`: SceneError, one line, at the first problem.  The
    value back normalised: a copy with every declared default filled in, so readers repeat none."""
    if not isinstance(value, dict):
        keys = ", ".join(f.name for f in table.fields)
        raise SceneError(f"{where}: {shown(value)} is not valid; allowed: a table {{ {keys} }}")
    return _record(value, table, where, "", registries or {})


def check_value(value: Any, field: Field, where: str, registries: Registries | None = None) -> Any:
    """Check one value against one field (e.g. a name taken from a file name); the value back, normalised."""
    return _value(value, field, where, field.name, registries or {})


def row_where(where: str, name: str, number: int, item: Any, table: Table) -> str:
    """Where a row of a list of tables is, as messages name it: `where: name[number] (id)`."""
    label = item.get(table.key) if table.key and isinstance(item, dict) else None
    if isinstance(label, str):
        shown_label = label if label.isprintable() and len(label) <= 60 else shown(label)
        return f"{where}: {name}[{number}] ({shown_label})"
    return f"{where}: {name}[{number}]"


def _invalid(where: str, path: str, value: Any, allowed: str) -> SceneError:
    return SceneError(f"{where}: {path}={shown(value)} is not valid; allowed: {allowed}")


def _record(item: Any, table: Table, where: str, prefix: str, reg: Registries) -> dict[str, Any]:
    fields = {f.name: f for f in table.fields}
    what = table.title
    if table.variant:
        chosen = fields[table.variant]
        value = item.get(table.variant, chosen.default)
        _value(value, chosen, where, prefix + chosen.name, reg)
        fields |= {f.name: f for f in reg[chosen.registry][value]}
        what = f"{what} with {table.variant}={shown(value)}"
    unknown = sorted(set(item) - set(fields), key=str)
    if unknown:
        raise SceneError(f"{where}: {prefix}{unknown[0]} is not a field of {what}; allowed: {', '.join(fields)}")
    out = dict(item)
    for f in fields.values():
        if f.name in item:
            out[f.name] = _value(item[f.name], f, where, prefix + f.name, reg)
        elif f.required:
            raise SceneError(f"{where}: {prefix}{f.name} is missing; allowed: {f.allowed(reg)}")
        elif f.default is not None:
            out[f.name] = copy.deepcopy(f.default)
    given = [k for k in table.one_of if k in item]
    if table.one_of and len(given) != 1:
        keys = ", ".join(prefix + k for k in table.one_of)
        raise SceneError(f"{where}: {' and '.join(prefix + k for k in given) or 'none of ' + keys} "
                         f"{'is' if len(given) < 2 else 'are'} given; allowed: exactly one of {keys}")
    return out


def _value(value: Any, f: Field, where: str, path: str, reg: Registries) -> Any:
    if f.alternatives:
        fitting = next((a for a in f.alternatives if a.type_fits(value)), None)
        if fitting is None:
            raise _invalid(where, path, value, f.allowed(reg))
        return _value(value, fitting, where, path, reg)
    if f.kind == "tables":
        return _rows(value, f, where, path, reg)
    if f.kind in ("record", "table"):
        if not isinstance(value, dict):
            raise _invalid(where, path, value, f.allowed(reg))
        for key, item in value.items() if f.values else ():
            _value(item, f.values, where, f"{path}.{key}", reg)
        return _record(value, f.table, where, f"{path}.", reg) if f.kind == "record" else value
    if f.shape:
        items = value if isinstance(value, list) else [value] if f.shape == "value or list" else None
        if items is None or not f.min_items <= len(items) <= (f.max_items or len(items)):
            raise _invalid(where, path, value, f.allowed(reg))
        for item in items:
            if not f.fits(item, reg):
                raise _invalid(where, path, item, f.allowed(reg))
    elif not f.fits(value, reg):
        raise _invalid(where, path, value, f.allowed(reg))
    return value


def _rows(value: Any, f: Field, where: str, path: str, reg: Registries) -> list[dict[str, Any]]:
    table = f.table
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value) or len(value) < f.min_items:
        raise _invalid(where, path, value, f.allowed(reg))
    seen: dict[str, dict[Any, int]] = {u.name: {} for u in table.fields if u.unique}
    rows = []
    for number, item in enumerate(value, 1):
        at = row_where(where, path, number, item, table)
        rows.append(_record(item, table, at, "", reg))
        for name, numbers in seen.items():
            key = item.get(name, table.default_key.format(number) if name == table.key else None)
            if key is None:
                continue
            if key in numbers:
                article = "an" if name[0] in "aeiou" else "a"
                raise SceneError(f"{at}: {name}={shown(key)} is not valid; allowed: {article} {name} no other {path} "
                                 f"has ({path}[{numbers[key]}] has it)")
            numbers[key] = number
    return rows


# -- the study file ----------------------------------------------------------------------------------------
# Every field says what it is (`description`, rendered into docs/study-files.md by `schema_markdown`); a default
# that is a value is declared as one, a default that depends on the row (an id, the file's name) is in words.

MAX_CELLS = 10_000  # cells of one study file; a larger study needs --allow-large
SAFE_NAME = r"[A-Za-z0-9][A-Za-z0-9._-]{0,79}"  # a file or folder name: no dot first, no separator
NAME = Field("name", "text", "names the study and its report folder (default: the file's name without .toml)",
             hint="1 to 80 letters, digits, '.', '_' or '-', starting with a letter or digit", pattern=SAFE_NAME)
ID = Field("id", "text", "names the files of its tables and figures, and the table names claims read",
           hint=NAME.hint, pattern=SAFE_NAME, unique=True)
TITLE = Field("title", "text", "the heading in the report (default: the id)")
TEXT_TABLE = Field("", "scalar", shape="value or list", min_items=0)  # a value of select = { column = values }
PARAMS = "parameters { name = value, ... }; a number may be an expression of the resolution, as text"
SCENE_NAME = "a scene name (see `pcverify scenes`)"
BOX_DEFAULTS = Box()  # the paper's bar
HEAT_DEFAULTS = Conduction()

REFERENCE_KINDS = ("analytic", "extrapolated", "mesh-dependent", "same-grid", "theory", "paper", "self")
SENSES = ("within", "at-most", "at-least")
AGGREGATES = ("max", "min", "median", "mean")
CELL_STATUSES = ("ok", "unstable", "skipped", "non-stationary", "defect", "failed", "missing")
DESIGNS = ("sobol", "lhs")
ERRORS = ("relative", "absolute")


def _point(name: str, description: str) -> Field:
    return Field(name, "real", description, shape="list", min_items=3, max_items=3)


HELD = Table("held", (
    Field("face", "text", "a face held at the temperature", choices=FACES),
    _point("point", "a point [x, y, z] (m) held at the temperature: a node of the grid the solver discretises on"),
    _point("patch", "the centre [x, y, z] (m) of a sphere whose solid is held at the temperature"),
    Field("radius", "real", "the patch's radius (m); needed with patch"),
    Field("temperature", "real", "held temperature (K)", required=True)),
             one_of=("face", "point", "patch"))
SUPPORT = Table("supports", (
    Field("face", "text", "the face on frictionless supports (held along its normal only)", choices=FACES,
          required=True),
    Field("displacement", "real", "the face's displacement along its normal (m)", default=0.0)))
MATERIAL = Table("material", (
    Field("name", "text", "a label for the material (default: custom)"),
    Field("density", "real", "kg/m^3", required=True),
    Field("conductivity", "real", "W/(m K); needed for heat"),
    Field("heat_capacity", "real", "J/(kg K); needed for heat"),
    Field("youngs_modulus", "real", "Pa; needed for elasticity"),
    Field("poisson_ratio", "real", "needed for elasticity")))
SCENE = Table("[[scene]]", (
    Field("name", "text", "the name groups use", hint="text of 1 to 80 characters", pattern=r"(?s)(?=.*\S).{1,80}",
          required=True),
    Field("description", "text", "one line of text (default: scene NAME (defined in a study file))"),
    Field("box", "record", "dimensions in m (default the paper's bar); groups may vary them as scene parameters",
          table=Table("box", tuple(
              Field(k, "real", f"{what} (m)", low=EXTENT_RANGE[0], high=EXTENT_RANGE[1],
                    default=getattr(BOX_DEFAULTS, k))
              for k, what in (("width", "along x"), ("height", "along y"), ("length", "along z, the bar's axis"))))),
    Field("material", "any", "a shipped material by name, or a table of constants", default="aluminium",
          alternatives=(Field("material", "text", choices=tuple(MATERIALS)), Field("material", "record",
                                                                                 table=MATERIAL))),
    Field("t_max", "real", "temperature scale of the reported T / t_max (K)", default=HEAT_DEFAULTS.t_max),
    Field("mode", "text", "steady state, or a transient reported at t_end", choices=MODES, default=HEAT_DEFAULTS.mode),
    Field("t_end", "real", "end time of a transient (s)", default=HEAT_DEFAULTS.t_end),
    Field("dt", "real", "continuum time step of a transient (s); in (0, t_end]", default=HEAT_DEFAULTS.dt),
    Field("initial_temperature", "real", "temperature at t = 0 (K)", default=HEAT_DEFAULTS.initial_temperature),
    Field("source", "real", "uniform volumetric heat source (W/m^3)", default=HEAT_DEFAULTS.source),
    Field("interface", "record", "a planar heat source on an internal plane", table=Table("interface", (
        Field("flux", "real", "the heat the plane releases (W/m^2)", required=True),
        Field("position", "real", "where the plane crosses its axis (m)", required=True),
        Field("axis", "text", "the plane's normal: x, y or z (default z)")))),
    Field("held", "tables", "held temperatures: each a face, a point or a patch", table=HELD, min_items=0),
    Field("supports", "tables", "frictionless supports", table=SUPPORT, min_items=0),
    Field("clamps", "text", "faces held fixed in every direction", choices=FACES, shape="list", min_items=0),
    Field("modes", "int", "number of eigenfrequencies asked for (0: a static scene)", default=0),
), key="name")

GROUP = Table("[[group]]", (
    Field("id", "text", "names the group's tables and figures (G-cells, G-fits, ...; default: group<N>, N its "
          "number from 1)", hint=ID.hint, pattern=SAFE_NAME, unique=True),
    TITLE, Field("scene", "text", "the scene of every cell", hint=SCENE_NAME, required=True),
    Field("scene_params", "table", f"scene {PARAMS}"),
    Field("solvers", "text", "the solvers run", hint="a solver name or module:Class", shape="value or list",
          required=True),
    Field("n", "int", "lattice resolutions", low=2, high=1000, shape="value or list", default=[4]),
    Field("refine", "int", "grid refinements (h = a / refine)", low=1, high=1000, shape="value or list", default=[1]),
    Field("solver_params", "table", "solver parameters { name = value } shared, or { solver = { ... } } per solver; "
          "a number may be an expression of the resolution, as text"),
    Field("sweep", "table", "{ parameter = [values] } (the product is run)",
          values=Field("", "scalar", shape="value or list")),
    Field("analysis", "text", "what the group's cells compute and tabulate (its options below)", registry="analyses",
          default="table"),
    Field("serial", "bool", "timed serially after a warm-up (default: the analysis's own: timing and "
          "work-precision are)"),
    Field("vtu", "bool", "write VTU point clouds", default=False),
    Field("repeats", "int", "a timed group's solves per cell (the least CPU time is kept; repeated only while a solve "
          "takes under 0.5 s)", low=1, high=20, default=3),
    Field("figures", "text", "figures besides the analysis's own: edge-profiles (the paper's Fig. 9), render-3d "
          "(the particles coloured by value), history (a cell's history against time over its scene's reference "
          "curve), parameter (figure_y against figure_x)", registry="figures", shape="value or list", min_items=0,
          default=[]),
    Field("figure_x", "text", "the parameter figure's x axis: a swept solver or scene parameter, n, refine or h"),
    Field("figure_y", "text", "the parameter figure's metrics: summary scalars or err.SET.NORM",
          shape="value or list", default=["err.nodes.l2", "err.nodes.linf"]),
), key="id", default_key="group{}", variant="analysis")

CLAIM = Table("[[claim]]", (
    Field("id", "text", "names the claim (pcverify verdict STUDY CLAIM)", required=True, unique=True),
    Field("text", "text", "the statement, as the report shows it", required=True),
    Field("table", "text", "the table it reads: a group's or calibration's table name, e.g. G-fits", required=True),
    Field("metric", "text", "the column judged", required=True),
    Field("reference", "text", "the kind of reference the number stands on", choices=REFERENCE_KINDS, required=True),
    Field("tolerance", "real", "the bound around the target (absolute; with tolerance_rel, the two add up)", low=0.0),
    Field("tolerance_rel", "real", "a bound relative to the target: tolerance_rel x |target| (3 % of 8 413 Hz: "
          "tolerance_rel = 0.03); one of tolerance and tolerance_rel is required", low=0.0),
    Field("tolerance_basis", "text", "why the tolerance is what it is: \"derived: <the bound: discretisation, "
          "round-off, GCI>\" or \"measured: <the value or spread measured> (<factor>x)\"; the report flags a "
          "tolerance above 10x the deviation measured as loose unless it is derived",
          hint="derived: TEXT or measured: TEXT", pattern=r"(?s)(derived|measured): .{3,600}"),
    Field("target", "any", "the value claimed (unless against gives it): a number, \"reference:NAME\" (the scalar "
          "NAME of the scene's reference) or an expression of n, refine, a, h, pi, the scene's numeric parameters and "
          "material constants, the solver parameters the group's cells share, the claim's selected numbers and its "
          "reference scalars", default=0.0, alternatives=(Field("target", "real"), Field(
              "target", "text", hint="reference:NAME or an expression", pattern=r"(?s).{1,200}"))),
    Field("select", "table", "the rows read: { column = value or [values] }", values=TEXT_TABLE, default={}),
    Field("aggregate", "text", "how the rows of a case combine", choices=AGGREGATES, default="max"),
    Field("absolute", "bool", "judge |value| (e.g. a signed difference)", default=False),
    Field("per", "text", "the column(s) that split the claim into one case per value, or per combination of values "
          "(\"n\", [\"solver\", \"n\"]); default: one case", shape="value or list"),
    Field("against", "table", "rows whose value is the target: { column = value or [values] }, matched by the per "
          "value unless it names that column", values=TEXT_TABLE, default={}),
    Field("against_table", "text", "the table against reads (default: the claim's table)"),
    Field("against_metric", "text", "the column against reads (default: the metric)"),
    Field("uncertainty", "any", "a number, a column (the largest over the rows) or \"spread\" (the band of the "
          "mean over a case's rows, with aggregate = \"mean\": one-sided Student-t at 95 % for their number times "
          "the standard error); default: the table's <metric>_unc column",
          alternatives=(Field("uncertainty", "real"), Field("uncertainty", "text", hint="a column name"))),
    Field("at_error", "real", "a cost claim: the metric (e.g. cpu_s) at this error, interpolated log-log between "
          "the case's levels that bracket it (never extrapolated); with against, the target is the other rows' cost "
          "at the same error", low=0.0, low_open=True),
    Field("error_metric", "text", "the error column at_error reads (default: the table's only err.* column)"),
    Field("sense", "text", "within: |value - target| <= tolerance; at-most: value <= target + tolerance; at-least: "
          "value >= target - tolerance", choices=SENSES, default="within"),
    Field("statuses", "text", "cell statuses a case may stand on", choices=CELL_STATUSES, shape="list",
          default=["ok"]),
    Field("allow_skipped", "bool", "a case whose cells were all skipped is not-applicable instead of fail",
          default=False),
), key="id")

REFERENCE = Table("reference", (
    Field("solver", "text", "the reference solver", hint="a solver name", required=True),
    Field("n", "int", "its lattice resolution (default: the cell's own n)", low=2, high=1000),
    Field("refine", "int", "its refinement; three or more are Richardson-extrapolated", low=1, high=1000,
          shape="value or list", default=1),
    Field("solver_params", "table", f"solver {PARAMS}")))
CALIBRATION_CELL = Table("[[calibration.calibrate]] or [[calibration.validate]]", (
    Field("scene", "text", "the scene of the cell", hint=SCENE_NAME, required=True),
    Field("scene_params", "table", f"scene {PARAMS}"),
    Field("n", "int", "lattice resolutions (one cell each)", low=2, high=1000, shape="value or list", default=4),
    Field("refine", "int", "grid refinement", low=1, high=1000, default=1),
    Field("metric", "text", "what is compared", hint="a summary quantity or <samples>.l2 / .linf", pattern=r"(?s).+",
          required=True),
    Field("reference", "any", "what the metric is compared with: the scene's analytic solution, or a solver's value",
          required=True, alternatives=(
              Field("reference", "text", choices=("analytic",)), Field("reference", "record", table=REFERENCE))),
    Field("error", "text", "how the error is measured", choices=ERRORS, default="relative"),
))
PARAMETER = Table("[[calibration.parameter]]", (
    Field("name", "text", "the free parameter", hint="a solver parameter", required=True, unique=True),
    Field("low", "real", "its lower bound", required=True),
    Field("high", "real", "its upper bound", required=True),
    Field("log", "bool", "search in log space", default=False)), key="name")
CALIBRATION = Table("[[calibration]]", (
    Field("id", "text", "names the calibration's tables (C-summary, C-parameters, ...; default: calibration<N>)",
          hint=ID.hint, pattern=SAFE_NAME, unique=True),
    TITLE, Field("solver", "text", "the solver calibrated", hint="a solver name", required=True),
    Field("solver_params", "table", "its fixed parameters { name = value, ... }, the same in every cell"),
    Field("parameter", "tables", "the free parameters", required=True, table=PARAMETER),
    Field("calibrate", "tables", "the cells the parameters are fitted on", required=True, table=CALIBRATION_CELL),
    Field("validate", "tables", "the held-out cells they are judged on", required=True, table=CALIBRATION_CELL),
    Field("budget", "int", "solver runs of the search (at least one per calibration cell)", low=1, high=100_000,
          default=32),
    Field("design", "text", "the space-filling design", choices=DESIGNS, default="sobol"),
    Field("design_points", "int", "points of the design", low=1, high=4096, default=16),
    Field("starts", "int", "bounded Nelder-Mead searches, from the best design points", low=0, high=64, default=1),
    Field("seed", "int", "seed of the design", low=0, high=2**31 - 1, default=0),
    Field("replicas", "table", "{ parameter = [values] } runs at the optimum that measure the objective's noise (not "
          "a free parameter)", values=Field("", "scalar", shape="value or list")),
    Field("noise_factor", "real", "parameter sets within best + max(noise_factor x noise, noise_floor) of the "
          "objective make the calibrated ranges", low=0.0, high=100.0, default=2.0),
    Field("noise_floor", "real", "the least width of that band", low=0.0, default=0.0),
    Field("sensitivity_step", "real", "the one-at-a-time step, a fraction of each parameter's (log) range",
          low=1e-6, high=0.5, default=0.1),
    Field("tolerance", "real", "the largest validation error within tolerance (unset: none is)", low=0.0),
), key="id", default_key="calibration{}")

MUTANT = Table("[[mutant]]", (
    Field("name", "text", "names the mutant (--mutant NAME) and its cache folder", hint=NAME.hint, pattern=SAFE_NAME,
          required=True, unique=True),
    Field("package", "text", "the importable top-level package whose file is mutated", hint="a top-level package name",
          pattern=r"[A-Za-z_][A-Za-z0-9_]{0,79}", default="pcverify"),
    Field("file", "text", "the mutated module, relative to the package's folder",
          hint="a relative path of a .py file inside the package, e.g. solvers/particles/mca/contact.py",
          pattern=r"(?s).{1,300}", required=True),
    Field("find", "text", "the text replaced (find or diff)", hint="text of 1 or more characters", pattern=r"(?s).+"),
    Field("replace", "text", "what replaces it"),
    Field("count", "int", "how many times `find` occurs (each is replaced)", low=1, high=1000, default=1),
    Field("diff", "text", "a unified diff against the file (find or diff)", hint="text of 1 or more characters",
          pattern=r"(?s).+"),
    Field("breaks", "text", "the physics or numerics it breaks", hint="a sentence", pattern=r"(?s)(?=.*\S).+",
          required=True),
    Field("expect", "text", "claims expected to kill it (shown in the report)", hint="a claim id",
          shape="value or list", min_items=0),
), key="name", one_of=("find", "diff"))

PANEL_ROW = Table("[[panel.row]]", (
    Field("label", "text", "the quantity, as the panel shows it (with its unit)", pattern=r"(?s).{1,120}",
          required=True),
    Field("table", "text", "the table its values come from: a group's table name, e.g. G-cells or G-levels",
          required=True),
    Field("metric", "text", "the column shown", required=True),
    Field("select", "table", "the rows read: { column = value or [values] }; one row per solver is shown",
          values=TEXT_TABLE, default={}),
    Field("scale", "real", "values and reference are multiplied by it (1e-9: Pa to GPa)", low=0.0, low_open=True,
          default=1.0),
    Field("reference", "real", "the reference value (in the table's unit, before scale)"),
    Field("reference_table", "text", "a table whose value is the reference (instead of a number)"),
    Field("reference_metric", "text", "the column of reference_table read", default="extrapolated"),
    Field("reference_select", "table", "the row of reference_table read: { column = value }", values=TEXT_TABLE,
          default={}),
    Field("reference_kind", "text", "the kind of reference the number stands on", choices=REFERENCE_KINDS,
          required=True),
), key="label", one_of=("reference", "reference_table"))
PANEL = Table("[[panel]]", (
    Field("id", "text", "names the panel's table (<id>.csv) and its section in the report", hint=ID.hint,
          pattern=SAFE_NAME, required=True, unique=True),
    TITLE,
    Field("solvers", "text", "the solvers side by side, one column each (the tables' solver column)",
          hint="a solver name", shape="list", required=True),
    Field("row", "tables", "the quantities, one row each", table=PANEL_ROW, required=True),
), key="id")

TABLES = {"scene": SCENE, "group": GROUP, "claim": CLAIM, "calibration": CALIBRATION,
          "mutant": MUTANT, "panel": PANEL}  # [[<name>]] tables
WHAT_TABLES_ARE = {"scene": "scenes the study defines from the shipped building blocks",
                   "group": "groups of cells: one scene, its solvers, resolutions and parameters, and an analysis",
                   "claim": "statements judged on the study's tables: pass, fail or inconclusive",
                   "calibration": "a solver's free parameters fitted on some cells and judged on others",
                   "mutant": "deliberate defects the study's claims should catch (pcverify mutate)",
                   "panel": "quantities of several solvers and their reference side by side, read from the groups' "
                            "tables (shown in the report, not judged)"}
STUDY = Table("a study file", (
    NAME, Field("title", "text", "the study's heading in the report (default: the file's name without .toml)"),
    Field("plugins", "text", "modules imported in every worker (a module beside the study file needs no install)",
          hint="a dotted module name", shape="value or list", min_items=0),
    Field("shipped_mutants", "text", "shipped solvers whose mutants in the shipped studies' catalogues pcverify "
          "mutate also runs this study's claims against (those that edit a module the solver reaches)",
          hint="a shipped solver's name", shape="value or list", min_items=0),
    *(Field(name, "tables", WHAT_TABLES_ARE[name], table=table, min_items=0) for name, table in TABLES.items())))


def as_list(value: Any) -> list[Any]:
    """A checked "value or list" field as a list (a string is one value, never its characters)."""
    return value if isinstance(value, list) else [value]
