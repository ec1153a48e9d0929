"""``python -m hmpc_pin``: the ``hmpc-pin`` command line."""

from .cli import main

raise SystemExit(main())
