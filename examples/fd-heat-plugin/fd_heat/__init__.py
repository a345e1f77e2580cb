"""An example pcverify plugin: an explicit finite-difference heat solver and a scene of its own.

Written only against pcverify's public API (`import pcverify`).  Installed with pip, it registers the
solver `fd-heat` and the scene `long-bar-faces` through the entry points in its pyproject.toml.
"""
