"""A nonlocal (bond-based peridynamic) heat solver written only against pcverify's public API."""
