"""The documentation says what the code does, and points only inside the project.

- docs/study-files.md carries the study-file reference rendered from the schema's declarations
  (`pcverify.harness.study.schema_markdown`): it is regenerated here and compared, so a changed declaration fails
  until the page is regenerated with `python tests/test_docs.py --regenerate`; the defaults it states are the
  code's, and its first example is a study that loads;
- every relative link of README.md and docs/*.md points to a file that exists, and a `#section` to one of its
  headings;
- every option of every command is in docs/command-line.md, under the command's heading; each table a report
  writes is in docs/outputs.md's "Output tables"; the line counts given for example files are right;
- no comment, docstring or configuration file points outside the project (to a physics file or design notes
  that do not ship with it).
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from pathlib import Path

import pytest

from pcverify.harness.cli import build_parser
from pcverify.harness.study.calibspec import Calibration
from pcverify.harness.study.claims import Claim
from pcverify.harness.study.schema import CALIBRATION, CLAIM
from pcverify.harness.study.schema_markdown import BEGIN, END, study_file_reference
from pcverify.harness.study.study import load_study

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
STUDY_FILES = DOCS / "study-files.md"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]

# what used to point outside the project (written in pieces, so that this file does not match itself)
OUTSIDE = ("PHYSICS" ".md", "PHYSICS" " §", "../" "shared", "shared" "/", "DESIGN" ".md", "references/" "physics.md",
           "seed" " 001", "MCA" " seed")
SCANNED = {".py", ".toml", ".ini", ".md", ".txt", ".cfg", ".yaml", ".yml"}
NOT_SCANNED = {".git", ".tox", "reports", "__pycache__", "build", "dist", ".pytest_cache", ".hypothesis", ".venv"}


def regenerated(text: str) -> str:
    """docs/study-files.md with its generated section rendered again from the schema."""
    assert text.count(BEGIN) == 1 and text.count(END) == 1, "the generated section's markers"
    return text[:text.index(BEGIN)] + study_file_reference() + text[text.index(END) + len(END) + 1:]


def test_the_study_file_reference_is_the_schema_rendered() -> None:
    text = STUDY_FILES.read_text(encoding="utf-8")
    assert text == regenerated(text), (
        "docs/study-files.md differs from the schema's declarations: run python tests/test_docs.py --regenerate")


def _dataclass_default(cls: type, name: str) -> object:
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    return f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default


@pytest.mark.parametrize("table, cls", [(CLAIM, Claim), (CALIBRATION, Calibration)])
def test_the_defaults_the_reference_states_are_the_codes(table, cls) -> None:
    declared = {f.name: f.default for f in table.fields if f.default is not None}
    assert declared
    for name, default in declared.items():
        value = _dataclass_default(cls, name)
        assert (list(value) if isinstance(value, tuple) else value) == default, name


def test_the_first_example_study_loads(tmp_path) -> None:
    block = re.search(r"```toml\n(.*?)```", STUDY_FILES.read_text(encoding="utf-8"), re.S)
    (tmp_path / "example.toml").write_text(block[1])
    study = load_study(str(tmp_path / "example.toml"))
    assert [len(g.cells) for g in study.groups] == [6] and len(study.claims) == 1


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.replace("`", "").strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return {slug(h) for h in re.findall(r"^#{1,6} (.+)$", text, re.M)}


def links(page: Path) -> list[str]:
    """The link targets of a Markdown page, outside code blocks and code spans."""
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.findall(r"\[[^\]]*\]\(([^)\s]+)\)", text)


def test_every_relative_link_points_to_a_file_of_the_project() -> None:
    broken = []
    for page in PAGES:
        for target in links(page):
            if re.match(r"[a-z]+:", target):  # https:, mailto: ... : not a file of the project
                continue
            path, _, anchor = target.partition("#")
            where = (page.parent / path).resolve() if path else page
            if not where.exists():
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and where.suffix == ".md" and anchor not in anchors(where):
                broken.append(f"{page.relative_to(ROOT)}: {target} (no such heading)")
    assert len(PAGES) > 5 and not broken, "\n".join(broken)


def _options(parser: argparse.ArgumentParser) -> list[str]:
    return [o for a in parser._actions for o in a.option_strings if o not in ("-h", "--help")]


def test_every_option_of_every_command_is_documented() -> None:
    text = (DOCS / "command-line.md").read_text(encoding="utf-8")
    parser = build_parser()
    missing = [o for o in _options(parser) if f"`{o}" not in text]
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    for name, sub in commands.items():
        start = text.index(f"\n## pcverify {name}\n")
        section = text[start:text.index("\n## ", start + 1)]
        missing += [f"{name} {o}" for o in _options(sub) if f"`{o}" not in section]
    assert not missing, missing


def test_every_table_a_report_writes_is_documented() -> None:
    """Each table name suffix the harness writes (`f"{id}-cells"`, ...) is in docs/outputs.md's "Output tables"."""
    text = (DOCS / "outputs.md").read_text(encoding="utf-8")
    section = text[text.index("## Output tables"):]
    section = section[:section.index("\n## ")]
    suffixes = set()
    for path in (ROOT / "harness").rglob("*.py"):
        suffixes |= set(re.findall(r"""\}-([a-z][a-z-]*)["']""", path.read_text()))
    assert {"cells", "fits", "levels", "skipped", "work-precision"} <= suffixes
    undocumented = sorted(s for s in suffixes if f"-{s}`" not in section)
    assert not undocumented, undocumented


def test_the_docs_count_the_example_files_lines_right() -> None:
    """Every "`examples/...py` (N lines)" in the README and docs/ is that file's line count."""
    found = [m for page in PAGES for m in re.findall(r"`(examples/[\w./-]+\.py)` \((\d+) lines\)", page.read_text())]
    assert found
    for path, count in found:
        assert len((ROOT / path).read_text().splitlines()) == int(count), path


def scanned_files() -> list[Path]:
    """The project's source, configuration and documentation files (as `grep -r --include` would see them)."""
    out = []
    for path in sorted(ROOT.rglob("*")):
        parts = path.relative_to(ROOT).parts
        if any(p in NOT_SCANNED or p.endswith(".egg-info") for p in parts[:-1]) or not path.is_file():
            continue
        if path.suffix in SCANNED or parts[0] == ".ci":
            out.append(path)
    return out


def test_nothing_points_outside_the_project() -> None:
    """No comment, docstring or configuration names a file that does not ship with the project."""
    files = scanned_files()
    assert ROOT / "pyproject.toml" in files and ROOT / "tox.ini" in files and ROOT / ".ci" / "run" in files
    found = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}" for path in files
             for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1)
             if any(word in line for word in OUTSIDE)]
    assert not found, "\n".join(found)


if __name__ == "__main__":
    if sys.argv[1:] != ["--regenerate"]:
        sys.exit("usage: python tests/test_docs.py --regenerate   (rewrites the reference in docs/study-files.md)")
    STUDY_FILES.write_text(regenerated(STUDY_FILES.read_text(encoding="utf-8")), encoding="utf-8")
    print(f"wrote {STUDY_FILES}")
