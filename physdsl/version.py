"""The version of physdsl, one place (the package root, run.json and proto-programs read it)."""

__version__ = "0.1.0"
