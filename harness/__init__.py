"""pcverify harness, grouped by what it does, each layer importing only those below it:

- `study`: what a study asks for (the study file and its schema, scenes, plugins, claims, analyses, cell tasks);
- `judge`: pure measures of results (metrics, the compare step, tables, verdicts);
- `run`: computing cells (execution, the cache, worker processes, limits, interrupts, calibration);
- `report`: what a reader sees (tables and figures on disk, the HTML page, findings, reproduction commands);
- `cli`: the command line on top.
"""
