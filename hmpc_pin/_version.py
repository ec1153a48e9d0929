"""The package's version, on the ground floor: importing it imports nothing else."""

__version__ = "0.3.0.dev0"  # the same as pyproject.toml (tested)
