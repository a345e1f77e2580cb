"""The command line as a newcomer uses it: help, scenes, errors as one line with exit code 2."""

import json

import pytest

from harness.cli import main


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for word in ("scenes", "solvers", "run", "study", "report", "--set KEY=VALUE"):
        assert word in out


def test_scenes_json_lists_catalogue(capsys):
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    names = [r["name"] for r in rows]
    assert names[:3] == ["bar-heat-paper", "bar-heat-patch", "bar-heat-faces"]
    rho = [p for p in rows[1]["parameters"] if p["name"] == "rho"][0]
    assert rho["default"] == 0.001 and rho["unit"] == "m" and "0.004" in rho["allowed"]


@pytest.mark.parametrize(
    "argv, word",
    [
        (["run", "bar-heat-nope", "--solver", "skfem"], "scene='bar-heat-nope'"),
        (["run", "bar-heat-paper", "--solver", "nope"], "solver='nope'"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "placement=front"], "placement"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "t_max=nan"], "t_max"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "bogus=1"], "bogus"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "novalue"], "KEY=VALUE"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--n", "1"], "n=1"),
    ],
)
def test_bad_input_is_one_line_error(argv, word, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("pcverify: error:") and word in err
    assert "\n" not in err and "Traceback" not in err
