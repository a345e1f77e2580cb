"""What a reader sees: each study's tables and figures on disk, the HTML page and its findings, provenance and
the command that reproduces every number."""
