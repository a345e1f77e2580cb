"""An example pcverify plugin: an explicit finite-difference heat solver and scenes of its own with their reference.

Written only against pcverify's public API (`import pcverify`).  Installed with pip, it registers the
solver `fd-heat` and the scenes `long-bar-faces` and `long-bar-source` through the entry points in its
pyproject.toml.
"""
