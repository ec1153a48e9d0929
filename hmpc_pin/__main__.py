"""``python -m hmpc_pin``: the ``hmpc-pin`` command line."""

from .apps.cli import main

if __name__ == "__main__":  # importing the module (documentation tools do) runs nothing
    raise SystemExit(main())
