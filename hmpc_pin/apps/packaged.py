"""``hmpc-pin configs`` and ``hmpc-pin examples``: what the wheel ships, listed and copied.

A pip install has no clone's ``configs/`` or ``examples/`` folder: these commands list the
packaged configs (name and description) and example scripts (name and first docstring
line), and write an editable copy of one of them. A config's copy is the packaged file as
it is (comments kept) with the side files it names by a relative path (the trajectory of
``panda_trajectory``) copied beside it, so that the copy runs where it is written; an
example's copy runs with ``python FILE``. Like ``init``, an existing file is not replaced
without ``--force``.
"""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

from ..data import config_names, config_path, example_names, example_path
from ..exceptions import ConfigError, OutputError

__all__ = [
    "CONFIG_HELP",
    "config_description",
    "configs_arguments",
    "copy_config",
    "copy_example",
    "example_description",
    "examples_arguments",
]

#: The help of every command's CONFIG argument.
CONFIG_HELP = "experiment TOML file, or the name of a packaged config (`hmpc-pin configs`)"


def config_description(name: str) -> str:
    """The ``description`` of the packaged config ``name`` (empty if it has none)."""
    path = config_path(name)
    raw = tomllib.loads(path.read_text(encoding="utf-8")) if path is not None else {}
    return str(raw.get("description", ""))


def example_description(name: str) -> str:
    """The first line of the packaged example ``name``'s docstring."""
    path = example_path(name)
    text = path.read_text(encoding="utf-8") if path is not None else ""
    doc = text.split('"""', 2)[1] if text.startswith('"""') else ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def _side_files(path: Path) -> list[Path]:
    """The files the config ``path`` names by a path relative to its folder."""
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    names = [
        raw.get("robot", {}).get("urdf"),
        raw.get("plant", {}).get("urdf"),
        raw.get("reference", {}).get("trajectory", {}).get("file"),
    ]
    return [path.parent / n for n in names if isinstance(n, str) and not Path(n).is_absolute()]


def _target(out: Path | None, default: str, force: bool) -> Path:
    path = Path(out) if out is not None else Path(default)
    if path.is_dir():
        raise OutputError(path, "is a directory", "--out", what="output file")
    if path.exists() and not force:
        raise ConfigError(
            "--out", f"{str(path)!r} exists; pass --force to replace it, or another path"
        )
    return path


def _copy(pairs: list[tuple[Path, Path]]) -> None:
    try:
        for src, dst in pairs:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)
    except OSError as exc:
        raise OutputError(dst.parent, f"is not writable ({exc.strerror or exc})", "--out") from exc


def copy_config(name: str, out: Path | None = None, force: bool = False) -> list[Path]:
    """Write an editable copy of the packaged config ``name`` to ``out`` (default
    ``<name>.toml`` here), with its side files beside it; return the files written.

    Raises:
        ConfigError: No packaged config ``name``; ``out`` or a side file exists (and not
            ``force``). OutputError: ``out`` cannot be written.
    """
    src = config_path(name)
    if src is None:
        raise ConfigError("NAME", f"no packaged config {name!r}; expected one of {config_names()}")
    path = _target(out, src.name, force)
    sides = _side_files(src)
    pairs = [(src, path)] + [(s, path.parent / s.name) for s in sides]
    if not force:
        for s, d in pairs[1:]:
            if d.exists() and d.read_bytes() != s.read_bytes():
                raise ConfigError(
                    "--out",
                    f"{str(d)!r} (which {src.name} needs beside it) exists and differs; "
                    "pass --force to replace it, or another folder",
                )
    _copy(pairs)
    return [d for _, d in pairs]


def copy_example(name: str, out: Path | None = None, force: bool = False) -> Path:
    """Write a copy of the packaged example script ``name`` to ``out`` (default
    ``<name>.py`` here) and return its path.

    Raises:
        ConfigError: No packaged example ``name``; ``out`` exists (and not ``force``).
        OutputError: ``out`` cannot be written.
    """
    src = example_path(name)
    if src is None:
        raise ConfigError(
            "NAME", f"no packaged example {name!r}; expected one of {example_names()}"
        )
    path = _target(out, src.name, force)
    _copy([(src, path)])
    return path


def _list(names, describe) -> None:
    width = max(len(n) for n in names)
    for n in names:
        print(f"{n:<{width}}  {describe(n)}")


def cmd_configs(args) -> int:
    """``hmpc-pin configs [copy NAME --out FILE]``."""
    if args.action is None:
        _list(config_names(), config_description)
        print(
            "run one by name (hmpc-pin run paper_combined); write an editable copy with "
            "hmpc-pin configs copy NAME --out FILE"
        )
        return 0
    files = copy_config(args.name, args.out, args.force)
    print(f"wrote {', '.join(str(f) for f in files)}; run it with: hmpc-pin run {files[0]}")
    return 0


def cmd_examples(args) -> int:
    """``hmpc-pin examples [copy NAME --out FILE]``."""
    if args.action is None:
        _list(example_names(), example_description)
        print("write a copy to run with: hmpc-pin examples copy NAME --out FILE")
        return 0
    path = copy_example(args.name, args.out, args.force)
    print(f"wrote {path}; run it with: python {path}")
    return 0


def _copy_arguments(parser, what: str, suffix: str) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION")
    copy = sub.add_parser("copy", help=f"write an editable copy of a packaged {what}")
    copy.add_argument("name", metavar="NAME", help=f"the {what}'s name (as listed)")
    copy.add_argument("--out", type=Path, default=None, help=f"file to write [NAME{suffix}, here]")
    copy.add_argument("--force", action="store_true", help="replace existing files")


def configs_arguments(parser) -> None:
    """``hmpc-pin configs``."""
    parser.description = (
        "List the configs shipped with the package (name and description; any command "
        "takes a name where it takes a config file), or write an editable copy of one "
        "(`copy NAME --out FILE`, with the side files it needs, e.g. a trajectory file), "
        "which runs where it is written."
    )
    _copy_arguments(parser, "config", ".toml")


def examples_arguments(parser) -> None:
    """``hmpc-pin examples``."""
    parser.description = (
        "List the example scripts shipped with the package, or write a copy of one "
        "(`copy NAME --out FILE`) to read, edit and run with `python FILE`."
    )
    _copy_arguments(parser, "example", ".py")
