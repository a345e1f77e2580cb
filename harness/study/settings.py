"""The --set KEY=VALUE settings of `pcverify run`, split into the scene's and the solver's parameters and parsed:
apart from the run so that the command line checks them before it imports a solver."""

from __future__ import annotations

from typing import Any

from pcverify.scene import Param, SceneError, shown


def split_settings(settings: list[str], scene_params: tuple[Param, ...], solver_params: tuple[Param, ...]
                   ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Route --set KEY=VALUE to the scene or the solver, parsing each value with its Param spec."""
    scene_spec = {p.name: p for p in scene_params}
    solver_spec = {p.name: p for p in solver_params}
    scene_vals: dict[str, Any] = {}
    solver_vals: dict[str, Any] = {}
    for item in settings:
        if "=" not in item:
            raise SceneError(f"--set {shown(item)}: expected KEY=VALUE")
        key, text = item.split("=", 1)
        key = key.strip()
        target = None
        if key.startswith("scene."):
            key, target = key[6:], "scene"
        elif key.startswith("solver."):
            key, target = key[7:], "solver"
        elif key in scene_spec and key in solver_spec:
            raise SceneError(f"--set {shown(key)}: both the scene and the solver have it; "
                             f"write scene.{key} or solver.{key}")
        elif key in scene_spec:
            target = "scene"
        elif key in solver_spec:
            target = "solver"
        else:
            known = sorted(set(scene_spec) | set(solver_spec))
            raise SceneError(f"--set {shown(key)}: unknown parameter; known: {', '.join(known)}")
        spec = scene_spec if target == "scene" else solver_spec
        if key not in spec:
            raise SceneError(f"--set {target}.{shown(key)}: unknown {target} parameter; known: "
                             f"{', '.join(sorted(spec))}")
        (scene_vals if target == "scene" else solver_vals)[key] = spec[key].parse(text)
    return scene_vals, solver_vals
