"""pcverify harness: scenes, studies, metrics, cache, execution, report, command line."""

__version__ = "0.1.0"
