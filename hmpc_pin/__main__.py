"""``python -m hmpc_pin``: the ``hmpc-pin`` command line."""

from .apps.cli import main

raise SystemExit(main())
