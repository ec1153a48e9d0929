"""Every bad input of issue 7, item 1: one case each, through the CLI and the library.

For each case the CLI exits 2 with a single ``error: …`` line on stderr naming the
file / key / joint and what was expected, no traceback, and writes no output file; the
library raises a typed subclass of :class:`hmpc_pin.HmpcError`.
"""

from __future__ import annotations

import re
import sys

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import (
    ConfigError,
    DimensionError,
    HmpcError,
    LimitError,
    OutputError,
    SimulationError,
    URDFError,
)
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.model.planar import KinematicsError

from .conftest import CONFIGS, PLANAR3

URDF = PLANAR3.as_posix()
BASE = (
    (CONFIGS / "paper_combined.toml").read_text().replace('model = "planar3"', f'urdf = "{URDF}"')
)


def _sub(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def _urdf(tmp, name: str, content: bytes | str):
    path = tmp / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path.as_posix()


NO_JOINT = """<robot name="stick"><link name="a"/><link name="b"/>
<joint name="weld" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"""

# Each case: tmp_path -> config text (or None for "no file"), expected exception, words the
# message must contain (the key/file/joint and what was expected).
CASES = {
    # --- URDF
    "urdf missing": (
        lambda tmp: _sub(URDF, (tmp / "gone.urdf").as_posix()),
        ConfigError,  # when the config is read: the key, the path tried
        ["robot.urdf", "gone.urdf' not found", "tried"],
    ),
    "urdf unreadable": (
        lambda tmp: _sub(URDF, _urdf(tmp, "bin.urdf", b"\xff\xfe\x00\x81 not text")),
        URDFError,
        ["bin.urdf", "cannot be read"],
    ),
    "urdf is a directory": (
        lambda tmp: _sub(URDF, tmp.as_posix()),
        ConfigError,
        ["robot.urdf", "is not a file"],
    ),
    "urdf malformed XML": (
        lambda tmp: _sub(URDF, _urdf(tmp, "bad.urdf", "<robot name='x'><link name='a'></robot>")),
        URDFError,
        ["bad.urdf", "malformed XML at line 1, column"],
    ),
    "urdf without actuated joint": (
        lambda tmp: _sub(URDF, _urdf(tmp, "stick.urdf", NO_JOINT)),
        URDFError,
        ["stick.urdf", "no actuated joint"],
    ),
    "urdf limits lower >= upper": (
        lambda tmp: _sub(
            URDF,
            _urdf(
                tmp,
                "crossed.urdf",
                PLANAR3.read_text().replace('lower="-1.5707963267948966"', 'lower="1.6"', 1),
            ),
        ),
        URDFError,
        [
            "crossed.urdf",
            "joint 'joint1' has an inverted position range",
            '<limit lower="1.6" upper="1.5708">',
            "controller.constraints.position = false",
        ],
    ),
    "unknown example-robot-data name": (
        lambda tmp: _sub(f'urdf = "{URDF}"', 'model = "ur55"'),
        URDFError,
        ["ur55", "did you mean 'ur5'"],
    ),
    # --- config file
    "config missing": (lambda tmp: None, ConfigError, ["cfg.toml", "not found"]),
    "config not TOML": (lambda tmp: "[controller\nN = 3\n", ConfigError, ["not valid TOML"]),
    "config not UTF-8": (lambda tmp: b"name = '\xff'\n", ConfigError, ["not a text file"]),
    "unknown top-level key": (
        lambda tmp: BASE + "\n[simulaton]\nduration = 1.0\n",
        ConfigError,
        ["simulaton", "unknown key"],
    ),
    "unknown key in a table": (
        lambda tmp: _sub("Nc = 1 ", "Nc = 1\nhorizon = 3 "),
        ConfigError,
        ["controller.horizon", "unknown key", "allowed keys"],
    ),
    "wrong type (string for integer)": (
        lambda tmp: _sub("N = 10 ", 'N = "10" '),
        ConfigError,
        ["controller.N", "expected an integer"],
    ),
    "wrong type (table expected)": (
        lambda tmp: _sub("Nc = 1 ", "Nc = 1\nconstraints = 3 "),
        ConfigError,
        ["controller.constraints", "expected a table"],
    ),
    "vector of wrong length (q0)": (
        lambda tmp: _sub("q0 = [1.0, 1.0, 1.0]", "q0 = [1.0, 1.0]"),
        ConfigError,
        ["simulation.q0", "2 entries", "3 joints"],
    ),
    "vector of wrong length (friction)": (
        lambda tmp: _sub("viscous = [10.0, 8.0, 5.0]", "viscous = [10.0, 8.0, 5.0, 1.0]"),
        ConfigError,
        ["disturbance.friction.viscous", "4 entries", "3 joints"],
    ),
    "Ts zero": (lambda tmp: _sub("Ts = 0.01", "Ts = 0.0"), ConfigError, ["controller.Ts", "> 0"]),
    "Ts negative": (
        lambda tmp: _sub("Ts = 0.01", "Ts = -0.01"),
        ConfigError,
        ["controller.Ts", "> 0"],
    ),
    "N zero": (lambda tmp: _sub("N = 10 ", "N = 0 "), ConfigError, ["controller.N", ">= 1"]),
    "N negative": (lambda tmp: _sub("N = 10 ", "N = -2 "), ConfigError, ["controller.N", ">= 1"]),
    "duration zero": (
        lambda tmp: _sub("duration = 10.0", "duration = 0.0"),
        ConfigError,
        ["simulation.duration", "> 0"],
    ),
    "duration negative": (
        lambda tmp: _sub("duration = 10.0", "duration = -5.0"),
        ConfigError,
        ["simulation.duration", "> 0"],
    ),
    "Nc > N": (
        lambda tmp: _sub("Nc = 1 ", "Nc = 11 "),
        ConfigError,
        ["controller.Nc", "1 <= Nc <= N"],
    ),
    "v_min == v_max": (
        lambda tmp: _sub("v_min = -100.0", "v_min = 100.0"),
        ConfigError,
        ["controller.v_min", "must be < v_max"],
    ),
    "v_min > v_max on one joint": (
        lambda tmp: _sub("v_min = -100.0", "v_min = [-100.0, 200.0, -100.0]"),
        ConfigError,
        ["controller.v_min", "must be < v_max"],
    ),
    "Q indefinite": (
        lambda tmp: _sub("Q = [50.0, 0.0]", "Q = [[1.0, 2.0], [2.0, 1.0]]"),
        ConfigError,
        ["controller.Q", "positive semi-definite"],
    ),
    "P negative": (
        lambda tmp: _sub("P = [100.0, 0.0]", "P = [-100.0, 0.0]"),
        ConfigError,
        ["controller.P", "positive semi-definite"],
    ),
    "Q not symmetric": (
        lambda tmp: _sub("Q = [50.0, 0.0]", "Q = [[50.0, 1.0], [0.0, 1.0]]"),
        ConfigError,
        ["controller.Q", "symmetric"],
    ),
    "Q zero": (
        lambda tmp: _sub("Q = [50.0, 0.0]", "Q = [0.0, 0.0]"),
        ConfigError,
        ["controller.Q", "non-zero"],
    ),
    "R zero": (lambda tmp: _sub("R = 1e-6", "R = 0.0"), ConfigError, ["controller.R", "> 0"]),
    "R a boolean": (  # TOML's true is no number (Python's bool would pass as 1)
        lambda tmp: _sub("R = 1e-6", "R = true"),
        ConfigError,
        ["controller.R", "expected a number, got bool True"],
    ),
    "Q infinite": (
        lambda tmp: _sub("Q = [50.0, 0.0]", "Q = [inf, 1.0]"),
        ConfigError,
        ["controller.Q", "expected finite numbers"],
    ),
    "R negative": (lambda tmp: _sub("R = 1e-6", "R = -1e-6"), ConfigError, ["controller.R", "> 0"]),
    "initial state outside joint limits": (
        lambda tmp: _sub("q0 = [1.0, 1.0, 1.0]", "q0 = [1.0, 1.7, 1.0]"),
        LimitError,
        ["simulation.q0", "'joint2'", "outside its limits"],
    ),
    "reference of the wrong dimension": (
        lambda tmp: _sub("amplitude = 1.0", "amplitude = [1.0, 1.0]"),
        ConfigError,
        ["reference.amplitude", "2 entries", "3 joints"],
    ),
    "reference leaving the joint limits": (
        lambda tmp: _sub("amplitude = 1.0", "amplitude = [1.0, 1.0, 3.0]"),
        LimitError,
        ["'joint3'", "outside its limits"],
    ),
    "unreachable Cartesian goal": (
        lambda tmp: (
            (CONFIGS / "paper_cartesian.toml")
            .read_text()
            .replace('model = "planar3"', f'urdf = "{URDF}"')
            .replace("goal_position = [2.423, 2.234]", "goal_position = [4.0, 0.0]")
        ),
        KinematicsError,
        ["cannot reach tool (4, 0)"],
    ),
    "plant dt does not divide Ts": (
        lambda tmp: _sub("dt = 0.001", "dt = 0.003"),
        ConfigError,
        ["plant.dt", "does not divide"],
    ),
    "state bound not positive": (
        lambda tmp: _sub("state_bound = 1000.0", "state_bound = 0.0"),
        ConfigError,
        ["simulation.state_bound", "> 0"],
    ),
    "sweep range reversed": (
        lambda tmp: _sub("mass = [0.8, 1.2]", "mass = [1.2, 0.8]"),
        ConfigError,
        ["sweep.mass", "low <= high"],
    ),
    # an infinite number (TOML's inf) is no more a setting than nan: refused as not finite
    "gain infinite": (
        lambda tmp: _sub("gain = 100.0", "gain = inf"),
        ConfigError,
        ["controller.observer.gain", "finite", "inf"],
    ),
    "R minus infinite": (
        lambda tmp: _sub("R = 1e-6", "R = -inf"),
        ConfigError,
        ["controller.R", "finite", "-inf"],
    ),
    # a bandwidth of exactly 0 on one joint: no observer there, not a positive bandwidth
    "bandwidth zero on one joint": (
        lambda tmp: _sub("gain = 100.0", "bandwidth = [20.0, 0.0, 20.0]"),
        ConfigError,
        ["controller.observer.bandwidth", "values > 0", "[20.0, 0.0, 20.0]"],
    ),
}


def _nan_cases():
    """``nan`` (TOML's NaN literal) in place of every number of the paper config, one at a time."""
    cases = {}
    number = r"-?\d+(?:\.\d+)?(?:e-?\d+)?"
    for m in re.finditer(rf"^(\w+) = (\[?)({number})", BASE, flags=re.M):
        key = m.group(1)
        text = BASE[: m.start(3)] + "nan" + BASE[m.end(3) :]
        cases[f"nan in {key}"] = (lambda tmp, text=text: text, ConfigError, [key, "nan"])
    return cases


NAN_CASES = _nan_cases()
ALL = {**CASES, **NAN_CASES}


def test_nan_cases_cover_every_number_of_the_config():
    keys = {name.removeprefix("nan in ") for name in NAN_CASES}
    assert {"gravity", "Ts", "R", "Q", "P", "v_min", "gain", "dt", "amplitude", "viscous",
            "coulomb", "center", "sigma", "duration", "q0", "dq0", "frequency", "state_bound",
            "mass", "q_noise", "dq_noise", "delay", "rms_target"} <= keys  # fmt: skip


def _config_file(tmp_path, make):
    path = tmp_path / "cfg.toml"
    text = make(tmp_path)
    if isinstance(text, bytes):
        path.write_bytes(text)
    elif text is not None:
        path.write_text(text)
    return path


@pytest.mark.parametrize("case", sorted(ALL))
def test_cli_bad_input_exits_2_with_one_line_and_no_files(tmp_path, capsys, case):
    make, _, words = ALL[case]
    cfg = _config_file(tmp_path, make)
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--duration", "10"]) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w in err, (w, err)
    assert not out.exists() or not any(out.iterdir()), list(out.iterdir())


@pytest.mark.parametrize("case", sorted(ALL))
def test_library_raises_a_typed_package_error(tmp_path, case):
    make, kind, words = ALL[case]
    cfg = _config_file(tmp_path, make)
    assert issubclass(kind, HmpcError)
    with pytest.raises(kind) as info:
        Experiment.from_config(hmpc_pin.load_config(cfg))
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    if kind is ConfigError:  # every config error names the file, and no placeholder
        assert str(info.value).startswith(f"{cfg}: "), str(info.value)
        assert "<" not in str(info.value).removeprefix(f"{cfg}: ")[:8], str(info.value)


def test_config_errors_name_the_file(tmp_path):
    cfg = _config_file(tmp_path, lambda tmp: _sub("R = 1e-6", "R = 0.0"))
    with pytest.raises(ConfigError, match=re.escape(str(cfg))):
        hmpc_pin.load_config(cfg)


@pytest.mark.parametrize("text", [None, "[controller\nN = 3\n", b"name = '\xff'\n",
                                  "<robot name='x'/>"])  # fmt: skip
def test_an_unloadable_config_is_named_by_its_path_alone(tmp_path, text):
    """The file itself is wrong (missing, not TOML, not UTF-8, a URDF): the message is
    ``<path>: <what>``, no key and no placeholder in place of one; the same from
    write_config when its source cannot be read."""
    from hmpc_pin.experiment.config.write import write_config

    cfg = _config_file(tmp_path, lambda tmp: text)
    with pytest.raises(ConfigError) as info:
        hmpc_pin.load_config(cfg)
    assert info.value.key == "" and info.value.source == str(cfg)
    head, _, what = str(info.value).partition(": ")
    assert head == str(cfg) and what == info.value.message, str(info.value)
    if text is not None and not isinstance(text, bytes):
        with pytest.raises(ConfigError) as info:
            write_config(cfg, {}, tmp_path / "out.toml")
        assert str(info.value).startswith(f"{cfg}: cannot be read"), str(info.value)


# ------------------------------------------------------------- outputs and the library
def test_output_directory_not_writable(tmp_path, capsys, planar3):
    blocker = tmp_path / "file"
    blocker.write_text("")
    argv = ["run", str(CONFIGS / "paper_combined.toml"), "--out", str(blocker / "sub")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out: output directory") and "not writable" in err
    assert len(err.strip().splitlines()) == 1
    result = hmpc_pin.simulate(
        planar3, hmpc_pin.HierarchicalMPC(planar3), hmpc_pin.SineReference(3),
        duration=0.05, q0=np.zeros(3),
    )  # fmt: skip
    with pytest.raises(OutputError, match="not writable"):
        result.save(blocker / "sub" / "r.npz")
    assert not list(tmp_path.glob("**/*.part"))


class _Wrong:
    """A reference returning 2 joints for a 3-joint arm."""

    def sample(self, t):
        return np.zeros(2), np.zeros(2)


def test_reference_of_wrong_dimension_is_refused_before_the_run(planar3):
    with pytest.raises(DimensionError, match=r"q_ref has shape \(2,\).*3 joints"):
        hmpc_pin.simulate(
            planar3, hmpc_pin.HierarchicalMPC(planar3), _Wrong(), duration=0.1, q0=np.zeros(3)
        )


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--samples", "0"], "--samples: expected an integer >= 1"),
        (["--jobs", "0"], "--jobs: expected an integer >= 1"),
        (["--seed", "-1"], "--seed: expected an integer >= 0"),
        (["--duration", "nan"], "--duration"),
    ],
)
def test_sweep_bad_arguments(tmp_path, capsys, argv, words):
    out = tmp_path / "out"
    base = ["sweep", str(CONFIGS / "paper_combined.toml"), "--out", str(out), "--quiet"]
    assert main(base + argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and words in err and len(err.strip().splitlines()) == 1
    assert not out.exists() or not any(out.iterdir())


def test_sweep_unknown_variant_names_the_key(tmp_path, capsys):
    cfg = _config_file(tmp_path, lambda tmp: _sub('"no-ndo"]', '"magic"]'))
    assert main(["sweep", str(cfg), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "sweep.variants" in err and "'magic'" in err and str(cfg) in err


def test_dask_executor_without_dask_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # as if not installed
    argv = ["sweep", str(CONFIGS / "paper_combined.toml"), "--out", str(tmp_path / "o")]
    assert main([*argv, "--executor", "dask", "--samples", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "hmpc_pin[cluster]" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "error, code",
    [(SimulationError("the arm process failed to start"), 1), (ConfigError("k", "bad"), 2)],
)
def test_a_run_failure_reaching_the_command_line_exits_1_bad_input_2(
    monkeypatch, capsys, error, code
):
    """The exit codes' contract at the command line's top: a run that failed (a
    ``SimulationError`` that reaches it, e.g. an arm process that did not start) is 1, bad
    input 2, each as one ``error:`` line (the command itself replaced here)."""
    import hmpc_pin.apps.commands.init as init

    def fails(args):
        raise error

    monkeypatch.setattr(init, "main", fails)
    assert main(["init", "planar3"]) == code
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [f"error: {error}"]
