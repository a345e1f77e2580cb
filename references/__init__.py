"""Analytic solutions and figures taken from the papers (with their source)."""
