"""The commands of ``hmpc-pin``, one module each, every one exporting the same two entry
points that :data:`hmpc_pin.apps.cli.COMMANDS` registers:

* ``add_arguments(parser)``: the command's description and arguments;
* ``main(args) -> int``: run it on the parsed ``args`` and return the exit code
  (:mod:`hmpc_pin.apps.cli` maps the errors it raises to exit codes 1, 2 and 130).

A module here is light to import: the library behind a command (numpy, Pinocchio, the
experiment) is imported inside ``main``, or by ``add_arguments`` when the command's
arguments come from the library (``tune``, ``identify``, ``ros``, ...).
"""
