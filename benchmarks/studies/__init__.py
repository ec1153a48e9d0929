"""One-off studies of hmpc_pin, each a program a page of the documentation cites for its
figures (``python benchmarks/studies/NAME.py --help``); run from the repository root."""
