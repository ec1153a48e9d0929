"""``hmpc-pin identify`` on every run the package writes: each observer form read back
from the run's record, bad files refused in one line, NaN samples left out."""

from __future__ import annotations

import io
import json
import re
import tomllib
import zipfile
from dataclasses import replace

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.experiment.config.controller import ObserverConfig
from hmpc_pin.identification import ObserverModel, fit_friction
from hmpc_pin.sim.result import Result

from .conftest import CONFIGS

VISCOUS, COULOMB = np.array([10.0, 8.0, 5.0]), np.array([3.0, 2.4, 1.8])  # paper_friction


def _friction_config(
    compensation: str, observer: ObserverConfig, duration: float = 5.0, coulomb: str = "stick-slip"
):
    """paper_friction with this observer, for ``duration`` [s], its plant's Coulomb law
    ``coulomb`` (the default stick-slip: a joint at rest sticks at each reversal)."""
    config = load_config(CONFIGS / "paper_friction.toml")
    cc = replace(config.controller, compensation=compensation, observer=observer)
    pc = replace(config.plant, coulomb=coulomb)
    sim = replace(config.simulation, duration=duration)
    return replace(config, controller=cc, plant=pc, simulation=sim)


def _identify(path, tmp_path, capsys, *extra) -> tuple[int, str, str, dict | None]:
    out = tmp_path / "friction.toml"
    out.unlink(missing_ok=True)
    code = main(["identify", str(path), "--out", str(out), *extra])
    captured = capsys.readouterr()
    table = tomllib.loads(out.read_text()) if out.exists() else None
    return code, captured.out, captured.err, table


FORMS = {
    "chen gain": ("chen", ObserverConfig(gain=100.0)),
    "general bandwidth, model at start (init's)": (
        "general", ObserverConfig(bandwidth=np.array([15.0, 20.0, 20.0]), model_at="start")),
    "momentum gain": ("momentum", ObserverConfig(gain=50.0)),
    "momentum bandwidth per joint": (
        "momentum", ObserverConfig(bandwidth=np.array([10.0, 15.0, 20.0]))),
}  # fmt: skip


@pytest.mark.parametrize("law", ["stick-slip", "sign"])
@pytest.mark.parametrize("form", sorted(FORMS))
def test_every_observer_form_is_identified_from_its_record(form, law, tmp_path, capsys):
    """The run records the observer that ran; with it the observer's estimate gives the
    plant's friction (known: paper_friction) within 3 %, on either Coulomb law of the
    plant. Why 3 %: what is left is the sampling of a continuous disturbance by a
    discrete observer, first order in Ts (1–2.5 % at Ts = 10 ms, half that at 5 ms);
    a stuck joint's holding torque, which the law a q̇ + b sgn q̇ does not hold, is left
    out with the observer's settling after it (kept in, it biased joint 3's viscous
    coefficient by 4 % under a 15–20 rad/s observer)."""
    exp = Experiment.from_config(_friction_config(*FORMS[form], coulomb=law))
    path = exp.run().save(tmp_path / "run.npz")
    record = Result.load(path).meta["observer_model"]
    comp = exp.controller.compensation
    if hasattr(comp, "cY"):  # the matrix that ran, not a config key
        np.testing.assert_array_equal(record["matrix"], comp.cY)
    else:
        np.testing.assert_array_equal(np.broadcast_to(record["gain"], (3,)), comp.K)
    code, _out, err, table = _identify(path, tmp_path, capsys)
    assert code == 0, err
    fr = table["controller"]["friction"]
    np.testing.assert_allclose(fr["viscous"], VISCOUS, rtol=0.03)
    np.testing.assert_allclose(fr["coulomb"], COULOMB, rtol=0.03)


def test_an_explicit_observer_is_read_as_explicit(tmp_path):
    """Forward Euler is recorded and filtered as forward Euler (its record differs from
    the implicit one only there)."""
    exp = Experiment.from_config(
        _friction_config("general", ObserverConfig(gain=5.0, discretization="explicit"), 1.0)
    )
    record = exp.meta()["observer_model"]
    assert record["discretization"] == "explicit"
    assert ObserverModel.from_record(record, exp.robot, 3).implicit is False


def test_records_of_older_versions_are_read(tmp_path, capsys):
    """A file that records kind and gain (before the matrix) is read as that observer;
    one whose bandwidth observer recorded no gain is one line, not a traceback."""
    exp = Experiment.from_config(_friction_config("chen", ObserverConfig(gain=100.0)))
    result = exp.run()
    new = fit_friction(result, observer=ObserverModel.from_record(
        result.meta["observer_model"], exp.robot, 3))  # fmt: skip
    result.meta["observer_model"] = {"kind": "chen", "gain": 100.0, "Ts": 0.01,
                                     "discretization": "implicit"}  # fmt: skip
    result.meta["config"] = None
    code, _, err, table = _identify(result.save(tmp_path / "old.npz"), tmp_path, capsys)
    assert code == 0, err
    np.testing.assert_allclose(table["controller"]["friction"]["viscous"], new.viscous,
                               rtol=1e-5)  # fmt: skip
    result.meta["observer_model"] = {"kind": "general", "gain": None, "Ts": 0.01}
    code, _out, err, table = _identify(result.save(tmp_path / "bw.npz"), tmp_path, capsys)
    assert code == 2 and table is None
    assert len(err.strip().splitlines()) == 1 and "--source dynamics" in err, err


@pytest.mark.parametrize("reaction", ["ignore", "stop"])
def test_a_run_with_a_collision_reaction_records_its_observer(reaction, tmp_path, capsys):
    """``[collision]`` wraps the controller and gates its observer: the run still records
    the observer that ran (the same record as without the reaction), and ``identify``
    fits its estimate (no collision flagged: the threshold is above any estimate)."""
    from hmpc_pin.experiment.config.collision import CollisionConfig

    config = _friction_config("chen", ObserverConfig(gain=100.0))
    plain = Experiment.from_config(config).run()
    watched = Experiment.from_config(replace(config, collision=CollisionConfig(1e6, reaction)))
    result = watched.run()
    assert result.meta["observer_model"] == plain.meta["observer_model"]
    np.testing.assert_array_equal(result.d_hat, plain.d_hat)
    code, _out, err, table = _identify(result.save(tmp_path / "watched.npz"), tmp_path, capsys)
    assert code == 0 and table is not None, err


def test_a_run_that_does_not_say_which_observer_ran(saved_run, tmp_path, capsys):
    """Without the observer's record and without its config file the estimate cannot be
    unfiltered: ``--source observer`` (the default) is one line pointing to ``--source
    dynamics``, nothing written; with ``--source dynamics`` the same file is fitted."""
    result = Result.load(saved_run)
    result.meta.pop("observer_model", None)
    result.meta["config"] = None
    path = result.save(tmp_path / "anonymous.npz")
    for extra in ((), ("--source", "observer")):
        code, _out, err, table = _identify(path, tmp_path, capsys, *extra)
        assert code == 2 and table is None
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: --source:"), err
        assert "--source dynamics" in lines[0]
    code, _out, err, table = _identify(path, tmp_path, capsys, "--source", "dynamics")
    assert code == 0 and table is not None, err


@pytest.fixture(scope="module")
def saved_run(tmp_path_factory):
    exp = Experiment.from_config(_friction_config("chen", ObserverConfig(gain=100.0)))
    return exp.run().save(tmp_path_factory.mktemp("run") / "run.npz")


def _foreign_npz(path):
    np.savez(path, a=np.arange(3))


def _object_npz(path):
    np.savez(path, meta=np.array([{"a": 1}], dtype=object))


def _truncated(path, saved):
    data = saved.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _data_past_the_end(path, saved):
    """A zip whose last member's sizes (in the directory) and array header claim more
    data than the file holds: reading it runs into the file's end (``EOFError``, not
    ``BadZipFile``)."""
    with zipfile.ZipFile(saved) as src, zipfile.ZipFile(path, "w") as dst:
        names = [i.filename for i in src.infolist() if i.filename != "q.npy"] + ["q.npy"]
        for name in names:
            body = src.read(name)
            if name == "q.npy":  # a header claiming far more samples than follow
                q = np.load(io.BytesIO(body))
                head = io.BytesIO()
                header = {"descr": q.dtype.str, "fortran_order": False, "shape": (2**20, 3)}
                np.lib.format.write_array_header_1_0(head, header)
                body = head.getvalue() + q.tobytes()
            dst.writestr(name, body)
    data = bytearray(path.read_bytes())
    entry = data.rindex(b"PK\x01\x02")  # q.npy's directory entry
    for offset in (20, 24):  # compressed and uncompressed sizes: 2 GiB
        data[entry + offset : entry + offset + 4] = (2**31).to_bytes(4, "little")
    path.write_bytes(bytes(data))


def _npy(path, saved):
    np.save(path.with_suffix(".npy"), np.ones(3))
    path.with_suffix(".npy").rename(path)


def _zip(path, saved):
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("x.txt", "hello")


def _bad_shapes(path, saved):
    with np.load(saved) as f:
        arrays = dict(f)
    arrays["dq"] = arrays["dq"][:-3]
    np.savez(path, **arrays)


def _repeated_time(path, saved):
    with np.load(saved) as f:
        arrays = dict(f)
    arrays["t"] = arrays["t"].copy()
    arrays["t"][5] = arrays["t"][4]  # two samples at one instant
    np.savez(path, **arrays)


def _one_sample(path, saved):
    with np.load(saved) as f:
        arrays = dict(f)
    for name in ("t", "q", "dq", "tau", "d_hat", "tau_applied"):
        if name in arrays and arrays[name].ndim:
            arrays[name] = arrays[name][:1]
    np.savez(path, **arrays)


def _text_torque(path, saved):
    with np.load(saved) as f:
        arrays = dict(f)
    arrays["tau"] = arrays["tau"].astype(str)
    np.savez(path, **arrays)


def _short_column(name):
    def make(path, saved):
        with np.load(saved) as f:
            arrays = dict(f)
        arrays[name] = arrays[name][:-3]
        np.savez(path, **arrays)

    return make


def _fewer_joints(name):
    def make(path, saved):
        with np.load(saved) as f:
            arrays = dict(f)
        arrays[name] = arrays[name][:, :-1]  # every sample, one joint short
        np.savez(path, **arrays)

    return make


def _more_joints(name):
    def make(path, saved):
        with np.load(saved) as f:
            arrays = dict(f)
        arrays[name] = np.hstack([arrays[name], arrays[name][:, :1]])
        np.savez(path, **arrays)

    return make


def _meta_list(path, saved):
    with np.load(saved) as f:
        arrays = dict(f)
    arrays["meta"] = np.array(json.dumps(["not", "a", "table"]))
    np.savez(path, **arrays)


BAD_FILES = {
    "a torque of text": (_text_torque, "'tau' is not numeric"),
    "a torque of another length": (_short_column("tau"), "'tau' has shape"),
    "an estimate of another length": (_short_column("d_hat"), "'d_hat' has shape"),
    "an applied torque too short": (_short_column("tau_applied"), "'tau_applied' has shape"),
    "metadata that is not a table": (_meta_list, "metadata is not a table"),
    "a time stamp repeated": (_repeated_time, "not finite and increasing"),
    "one sample": (_one_sample, "at least 2 samples"),
    "empty": (lambda p, s: p.write_bytes(b""), "empty"),
    "a torque of fewer joints": (_fewer_joints("tau"), "'tau' has shape"),
    "an estimate of more joints": (_more_joints("d_hat"), "'d_hat' has shape"),
    "text": (lambda p, s: p.write_text("t,q\n0,1\n"), "not a .npz archive"),
    "text starting with PK": (lambda p, s: p.write_text("PK,q\n0,1\n"), "not a .npz archive"),
    "npy": (_npy, "not a .npz archive"),
    "truncated": (_truncated, "truncated or corrupt"),
    "data past the end": (_data_past_the_end, "truncated or corrupt (the data end early)"),
    "foreign npz": (lambda p, s: _foreign_npz(p), "has no 'meta' array"),
    "object arrays": (lambda p, s: _object_npz(p), "not a hmpc_pin result"),
    "arrays of different lengths": (_bad_shapes, "'dq' has shape"),
    "a zip of something else": (_zip, "not a hmpc_pin result"),
}


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_a_bad_file_is_one_line_and_exit_2(kind, saved_run, tmp_path, capsys):
    make, expected = BAD_FILES[kind]
    path = tmp_path / "bad.npz"
    make(path, saved_run)
    code, _out, err, table = _identify(path, tmp_path, capsys)
    assert code == 2 and table is None
    lines = err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(path) in lines[0], err
    assert "pickle" not in err and "Traceback" not in err


@pytest.mark.parametrize("kind", sorted(BAD_FILES))
def test_replay_reads_a_run_as_identify_does(kind, saved_run, tmp_path, capsys):
    """``replay`` refuses the same bad files with the same line (named RESULT), before
    anything is written."""
    make, expected = BAD_FILES[kind]
    path, html = tmp_path / "bad.npz", tmp_path / "replay.html"
    make(path, saved_run)
    code = main(["replay", str(path), "--out", str(html)])
    err = capsys.readouterr().err
    assert code == 2 and not html.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(path) in lines[0], err
    assert "RESULT" in lines[0] and "pickle" not in err and "Traceback" not in err


def test_replay_refuses_a_urdf_of_another_arm(saved_run, tmp_path, capsys):
    """A ``--urdf`` with other joints than the run's: one line naming both, exit 2."""
    urdf, html = tmp_path / "one.urdf", tmp_path / "replay.html"
    urdf.write_text(
        '<robot name="one"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>'
        "</robot>"
    )
    code = main(["replay", str(saved_run), "--urdf", str(urdf), "--out", str(html)])
    err = capsys.readouterr().err
    assert code == 2 and not html.exists()
    assert len(err.strip().splitlines()) == 1 and "--urdf" in err and "3 joints" in err, err


@pytest.mark.parametrize("source", ["observer", "dynamics"])
def test_nan_samples_are_left_out_with_a_count(source, saved_run, tmp_path, capsys):
    """NaN in q̇ for 5 samples: the fit leaves them out (the observer's filter starts
    again from rest after them: its start-up, --after = 0.5 s, is left out too, not the
    rest of the run) and says how many (not counting those before --after); with every
    sample NaN, one line and exit 2."""
    result = Result.load(saved_run)
    result.dq[300:305, 1] = np.nan
    if source == "dynamics":  # before --after (0.5 s): left out anyway, not counted
        result.dq[10:20, 0] = np.nan
    code, out, err, table = _identify(result.save(tmp_path / "nan.npz"), tmp_path, capsys,
                                      "--source", source)  # fmt: skip
    assert code == 0, err
    # dynamics: the 6 periods touching the 5 samples; observer: the 5 and 0.5 s after them
    restart = np.count_nonzero((result.t >= result.t[305]) & (result.t < result.t[305] + 0.5))
    excluded = 6 if source == "dynamics" else 5 + restart
    assert restart < len(result.t) - 305 - 10  # (the rest of the run is fitted)
    assert f"{excluded} samples left out" in out, out
    np.testing.assert_allclose(table["controller"]["friction"]["viscous"], VISCOUS, rtol=0.05)
    result.d_hat[:] = np.nan
    result.tau_applied[:] = np.nan
    code, out, err, table = _identify(result.save(tmp_path / "all.npz"), tmp_path, capsys,
                                      "--source", source)  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1 and "NaN" in err, err


def test_no_interval_without_enough_effective_samples(saved_run, tmp_path, capsys):
    """A residual that is a slow drift (a disturbance the friction model does not hold):
    lag-1 autocorrelation near 1, m_e near 0: the table says n/a and why, no interval."""
    result = Result.load(saved_run)
    result.d_hat += 2.0 * np.sin(0.3 * result.t)[:, None]  # smooth, unmodelled
    code, out, err, _table = _identify(result.save(tmp_path / "drift.npz"), tmp_path, capsys,
                                      "--source", "observer")  # fmt: skip
    assert code == 0, err
    assert "[n/a]" in out and "no confidence interval" in out, out
    fit_text = (tmp_path / "friction.toml").read_text()
    assert "n/a" in fit_text


def test_the_record_of_every_command_is_the_experiments():
    """run, realtime and ros all save ``Experiment.meta()`` (apps/run.py, realtime.py,
    ros.py): the record is JSON and rebuilds the observer's matrix of the controller."""
    exp = Experiment.from_config(
        _friction_config(*FORMS["general bandwidth, model at start (init's)"])
    )
    record = json.loads(json.dumps(exp.meta()))["observer_model"]
    model = ObserverModel.from_record(record, exp.robot, 3)
    np.testing.assert_array_equal(model.matrix, exp.controller.compensation.cY)
    assert model.model_at == "start" and model.Ts == exp.config.controller.Ts


def test_a_run_of_an_init_spatial_arm_is_identified(tmp_path, capsys):
    """``init ur5`` writes a bandwidth observer evaluated at the period's start, with a
    latency: identify reads the run (it crashed on it before) and the observer's
    estimate gives the friction the model's inverse dynamics gives (two independent
    measurements of it; the init's disturbance pulses are in both)."""
    toml = tmp_path / "ur5.toml"
    assert main(["init", "ur5", "--out", str(toml)]) == 0
    config = load_config(toml)
    assert config.controller.observer.bandwidth is not None
    ref = replace(config.reference, frequency=0.5)  # both ways within 2.5 s
    dq0 = config.simulation.dq0 * 5  # still on the reference: dr/dt(0) = 2π A f
    config = replace(config, reference=ref, simulation=replace(config.simulation, duration=2.5,
                                                              dq0=dq0))  # fmt: skip
    path = Experiment.from_config(config).run().save(tmp_path / "ur5.npz")
    capsys.readouterr()
    code, _out, err, obs = _identify(path, tmp_path, capsys, "--after", "0.3")
    assert code == 0, err
    code, _out, err, dyn = _identify(path, tmp_path, capsys, "--after", "0.3", "--source",
                                     "dynamics")  # fmt: skip
    assert code == 0, err
    a, b = obs["controller"]["friction"], dyn["controller"]["friction"]
    v = 2 * np.pi * np.asarray(ref.amplitude) * 0.5  # peak speed [rad/s]: torques there agree
    np.testing.assert_allclose(np.multiply(a["viscous"], v) + a["coulomb"],
                               np.multiply(b["viscous"], v) + b["coulomb"], rtol=0.05)  # fmt: skip


def _init_ur5_run(tmp_path, pulses: bool):
    """``init ur5``'s config moving both ways within 2.5 s (with or without the init's
    disturbance pulses), run and saved; with the friction it configures [N·m·s/rad, N·m]
    (``scale = "inertia"``: the coefficients times M_jj(q0))."""
    toml = tmp_path / "ur5.toml"
    assert main(["init", "ur5", "--out", str(toml)]) == 0
    config = load_config(toml)
    ref = replace(config.reference, frequency=0.5)
    dist = config.disturbance if pulses else replace(config.disturbance, pulse=None)
    config = replace(config, reference=ref, disturbance=dist, simulation=replace(
        config.simulation, duration=2.5, dq0=config.simulation.dq0 * 5))  # fmt: skip
    exp = Experiment.from_config(config)
    assert config.disturbance.scale == "inertia"
    m = np.diag(exp.robot.mass_matrix(exp.q0))
    fr = config.disturbance.friction
    true = (np.asarray(fr.viscous) * m, np.asarray(fr.coulomb) * m)
    return exp.run().save(tmp_path / "ur5.npz"), ref, true


def test_init_ur5_without_pulses_gives_the_configured_friction(tmp_path, capsys):
    """Pulses off, the plant's friction is the config's alone: the dynamics source (the
    applied torque against Pinocchio's model, exact here) gives it within 2 % (a Coulomb
    reversal inside a period biases the samples around it), the observer source the
    friction torque at the peak speed within 3 % (its lag and the model taken at the
    period's start, as for the planar forms)."""
    path, ref, (viscous, coulomb) = _init_ur5_run(tmp_path, pulses=False)
    capsys.readouterr()
    code, _out, err, dyn = _identify(path, tmp_path, capsys, "--after", "0.3", "--source",
                                     "dynamics")  # fmt: skip
    assert code == 0, err
    np.testing.assert_allclose(dyn["controller"]["friction"]["viscous"], viscous, rtol=0.02)
    np.testing.assert_allclose(dyn["controller"]["friction"]["coulomb"], coulomb, rtol=0.02)
    code, _out, err, obs = _identify(path, tmp_path, capsys, "--after", "0.3")
    assert code == 0, err
    a = obs["controller"]["friction"]
    v = 2 * np.pi * np.asarray(ref.amplitude) * 0.5  # peak speed [rad/s]
    np.testing.assert_allclose(np.multiply(a["viscous"], v) + a["coulomb"],
                               viscous * v + coulomb, rtol=0.03)  # fmt: skip


@pytest.mark.parametrize("flag", ["gravity_by_arm", "franka", "ros"])
def test_a_torque_without_gravity_is_fitted_with_gravity_added(flag, tmp_path, capsys):
    """A run whose arm added G(q) itself (Franka's FCI, a ROS arm with [ros] gravity =
    "arm") records the torque without it: the torque-based sources add G(q) back and find
    the configured friction as on the same run recorded with it (without, joint 2's and
    3's gravity would be read as friction)."""
    path, _ref, (viscous, coulomb) = _init_ur5_run(tmp_path, pulses=False)
    full = Result.load(path)
    exp = Experiment.from_config(load_config(tmp_path / "ur5.toml"))
    g = np.array([exp.robot.gravity_torque(q) for q in full.q])
    assert np.abs(g).max() > 10.0  # gravity is no small part of the torque here
    meta = dict(full.meta)
    if flag == "gravity_by_arm":  # as `hmpc-pin franka` writes it
        meta["gravity_by_arm"] = True
    elif flag == "franka":  # a Franka run of an earlier version
        meta["franka"] = {}
    else:  # `hmpc-pin ros` with [ros] gravity = "arm"
        meta["ros"] = {"gravity": "arm"}
    sent = replace(full, tau=full.tau - g, tau_applied=full.tau_applied - g, meta=meta)
    assert sent.gravity_by_arm and not full.gravity_by_arm
    sent.save(tmp_path / "sent.npz")
    capsys.readouterr()
    for source in ("dynamics", "regressor"):
        fits = []
        for run in (path, tmp_path / "sent.npz"):
            code, _out, err, table = _identify(run, tmp_path, capsys, "--after", "0.3",
                                               "--source", source)  # fmt: skip
            assert code == 0, err
            fits.append(table["controller"]["friction"])
        for key in ("viscous", "coulomb"):
            np.testing.assert_allclose(fits[1][key], fits[0][key], rtol=1e-6, atol=1e-9)
        if source == "dynamics":  # (the model exact here: the configured friction)
            np.testing.assert_allclose(fits[1]["viscous"], viscous, rtol=0.02)
            np.testing.assert_allclose(fits[1]["coulomb"], coulomb, rtol=0.02)


@pytest.mark.parametrize("source", ["observer", "dynamics"])
def test_with_the_pulses_the_advice_names_them(source, tmp_path, capsys):
    """init's disturbance pulses are not friction: where they leave too few effective
    samples for an interval, the note names the pulses (and --after), not a longer run,
    which would hold the same pulses."""
    path, _ref, _true = _init_ur5_run(tmp_path, pulses=True)
    capsys.readouterr()
    code, out, err, _table = _identify(path, tmp_path, capsys, "--after", "0.3", "--source",
                                       source)  # fmt: skip
    assert code == 0, err
    assert "[n/a]" in out, out  # the pulses at 1..6 s leave a correlated residual
    note = next(line for line in out.splitlines() if "no confidence interval" in line)
    assert "disturbance pulses" in note and "--after" in note, note
    assert "record a longer run" not in note, note


def test_a_closed_stdout_loses_no_file(saved_run, tmp_path):
    """`identify RUN | head`: stdout whose reader is gone (a pipe with its read end closed,
    unbuffered, so the first print fails): the table was written before anything was
    printed, so nothing is lost."""
    import os
    import subprocess
    import sys

    out = tmp_path / "f.toml"
    r, w = os.pipe()
    os.close(r)  # the reader is gone before the first byte
    try:
        cmd = [sys.executable, "-u", "-m", "hmpc_pin", "identify", str(saved_run), "--out",
               str(out)]  # fmt: skip
        subprocess.run(cmd, stdout=w, stderr=subprocess.PIPE, timeout=300)
    finally:
        os.close(w)
    assert tomllib.loads(out.read_text())["controller"]["friction"]["viscous"]


def _renamed_planar3(path):
    from .conftest import PLANAR3

    path.write_text(PLANAR3.read_text().replace('"joint1"', '"shoulder"'))
    return path


@pytest.mark.parametrize("source", ["observer", "dynamics"])
@pytest.mark.parametrize("arm", ["ur5 (6 joints)", "planar3 with a joint renamed"])
def test_the_urdf_of_another_arm_is_one_line(arm, source, saved_run, tmp_path, capsys):
    """``--urdf`` of an arm that did not run (another joint count, or the same count with
    other names) is refused naming both arms' joints: no Pinocchio size error."""
    from hmpc_pin.model.robot import load_robot

    urdf = (load_robot("ur5").source if arm.startswith("ur5")
            else str(_renamed_planar3(tmp_path / "renamed.urdf")))  # fmt: skip
    code, _out, err, table = _identify(saved_run, tmp_path, capsys, "--urdf", urdf,
                                       "--source", source)  # fmt: skip
    assert code == 2 and table is None, err
    assert len(err.strip().splitlines()) == 1 and "--urdf" in err, err
    assert "joint1" in err and ("shoulder" in err if "renamed" in arm else "6 joints" in err)


@pytest.mark.parametrize("mode", [(), ("--thresholds",)])
@pytest.mark.parametrize("after", ["1e9", "5", "nan"])
def test_after_past_the_end_of_the_run_is_named(after, mode, saved_run, tmp_path, capsys):
    """The saved run spans 0 to 5 s: --after at or past its end names --after and the
    run's length, not 'not excited enough (0 %)'."""
    t_end = float(Result.load(saved_run).t[-1])
    assert t_end == pytest.approx(5.0)
    code, _out, err, table = _identify(saved_run, tmp_path, capsys, "--after", after, *mode)
    assert code == 2 and table is None, err
    assert len(err.strip().splitlines()) == 1 and "--after" in err, err
    assert "past the end of the run" in err and f"{t_end:g} s" in err, err


def test_a_smoothed_feedforward_is_added_back_as_it_ran(tmp_path, capsys):
    """Half the friction fed forward with a smoothed sign, tanh(q̇/v_s) at v_s = 2 rad/s:
    identify adds back what was fed, so the fit is the plant's whole friction (known),
    within 3 % like every observer form (the exact sign in its place would add back
    b (1 - tanh(|q̇|/v_s)) too much)."""
    from hmpc_pin.experiment.config.friction import FrictionModelConfig

    config = _friction_config("chen", ObserverConfig(gain=100.0))
    ff = FrictionModelConfig(viscous=VISCOUS / 2, coulomb=COULOMB / 2, smoothing=2.0)
    config = replace(config, controller=replace(config.controller, friction=ff))
    path = Experiment.from_config(config).run().save(tmp_path / "ff.npz")
    assert Result.load(path).meta["friction_feedforward"]["smoothing"] == 2.0
    code, _out, err, table = _identify(path, tmp_path, capsys)
    assert code == 0, err
    fr = table["controller"]["friction"]
    np.testing.assert_allclose(fr["viscous"], VISCOUS, rtol=0.03)
    np.testing.assert_allclose(fr["coulomb"], COULOMB, rtol=0.03)


def test_a_file_without_a_record_reads_the_observer_of_its_config(tmp_path, capsys):
    """A run written before the observer was recorded: identify builds the observer from
    the config file the run names, and its dynamics give the plant's friction within
    3 %; the estimate taken as the disturbance itself is further off (the observer's
    lag: 13 % on a Coulomb coefficient)."""
    path = CONFIGS / "paper_friction.toml"
    result = Experiment.from_config(load_config(path)).run()
    assert result.meta["config"] == str(path)
    del result.meta["observer_model"]
    saved = result.save(tmp_path / "old.npz")
    code, _out, err, table = _identify(saved, tmp_path, capsys)
    assert code == 0, err
    fr = table["controller"]["friction"]
    np.testing.assert_allclose(fr["viscous"], VISCOUS, rtol=0.03)
    np.testing.assert_allclose(fr["coulomb"], COULOMB, rtol=0.03)
    raw = fit_friction(result, observer=None)  # the estimate as the disturbance itself
    off = np.concatenate([raw.viscous / VISCOUS, raw.coulomb / COULOMB]) - 1
    assert np.max(np.abs(off)) > 0.03, off


def test_a_recorded_matrix_of_another_size_is_one_line(saved_run, tmp_path, capsys):
    """The record's observer matrix must be n x n for the run's n joints: a 2 x 2 one for
    a 3-joint run is one line naming the shape expected, exit 2."""
    result = Result.load(saved_run)
    result.meta["observer_model"] = {"kind": "general", "Ts": 0.01,
                                     "matrix": np.eye(2).tolist()}  # fmt: skip
    code, _out, err, table = _identify(result.save(tmp_path / "m.npz"), tmp_path, capsys)
    assert code == 2 and table is None
    assert len(err.strip().splitlines()) == 1 and "(3, 3)" in err, err


@pytest.mark.parametrize(("option", "says"), [
    (["--thresholds", "--velocity-threshold", "0"],
     "--velocity-threshold: applies to friction identification only; drop it or --thresholds"),
    (["--false-alarm", "0"], "--false-alarm: applies to --thresholds only; add --thresholds or"),
])  # fmt: skip
def test_an_option_of_the_other_mode_given_as_zero_is_refused(option, says, saved_run,
                                                              tmp_path, capsys):  # fmt: skip
    """An option that does not apply is an error even when its value is 0, and the line
    says which mode it belongs to (friction's under --thresholds, and the other way)."""
    code, _out, err, table = _identify(saved_run, tmp_path, capsys, *option)
    assert code == 2 and table is None and says in err, err


def test_out_naming_a_folder_is_refused_before_any_work(saved_run, tmp_path, capsys):
    code = main(["identify", str(saved_run), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "--out" in err and "directory" in err, err


def test_the_runs_gravity_is_the_arms(saved_run):
    """run_robot builds the arm with the gravity the run recorded (a run on the Moon, or
    lying flat, is not identified under 9.81 m/s²)."""
    from hmpc_pin.apps.runfile import load_run, run_robot

    result = load_run(saved_run)
    result.meta["gravity"] = 1.62
    robot = run_robot(result, None)
    assert np.linalg.norm(robot.model.gravity.linear) == pytest.approx(1.62)


def test_thresholds_without_out_are_written_beside_the_run(saved_run, tmp_path, capsys):
    run = tmp_path / "contact_free.npz"
    run.write_bytes(saved_run.read_bytes())
    assert main(["identify", str(run), "--thresholds"]) == 0
    assert (tmp_path / "contact_free_collision.toml").is_file()
    assert not (tmp_path / "contact_free_friction.toml").exists()


def test_out_in_a_missing_folder_is_refused_before_any_work(saved_run, tmp_path, capsys):
    out = tmp_path / "no" / "such" / "friction.toml"
    code = main(["identify", str(saved_run), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "--out" in err and "no such directory" in err, err
    assert not (tmp_path / "no").exists()


def test_the_printed_thresholds_are_the_written_ones(saved_run, tmp_path, capsys):
    """Each joint's line: the threshold the TOML holds (4 digits) and the run's peak
    |d_hat| (numpy, over the whole run: --after 0)."""
    out = tmp_path / "collision.toml"
    assert main(["identify", str(saved_run), "--thresholds", "--out", str(out)]) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if ": threshold " in x]
    written = tomllib.loads(out.read_text())["collision"]["threshold"]
    peak = np.abs(Result.load(saved_run).d_hat).max(axis=0)
    assert len(lines) == 3
    for line, thr, pk in zip(lines, written, peak, strict=True):
        shown = line.split(": threshold ")[1]
        assert shown.startswith(f"{thr:.4g} N·m"), line
        assert shown.endswith(f"(peak |d_hat| in the run {pk:.4g})"), line
        assert thr >= 1.25 * pk * (1 - 1e-6)  # floored at the peak, times the safety


def test_a_velocity_threshold_of_zero_is_kept(saved_run, tmp_path, capsys):
    """--velocity-threshold 0 keeps every moving sample: the fit counts the samples the
    library counts with 0, more than with the default 0.01 rad/s."""
    from hmpc_pin.apps.identify import observer_model
    from hmpc_pin.apps.runfile import load_run, run_robot

    result = load_run(saved_run)
    model = observer_model(result, run_robot(result, None))
    fits = {v: fit_friction(result, observer=model, velocity_threshold=v) for v in (0.0, 0.01)}
    counts = {v: [j.samples for j in f.joints] for v, f in fits.items()}
    assert counts[0.0] != counts[0.01]
    code, out, err, _table = _identify(saved_run, tmp_path, capsys, "--velocity-threshold", "0")
    assert code == 0, err
    for j, name in enumerate(("joint1", "joint2", "joint3")):
        row = next(x for x in out.splitlines() if x.startswith(f"| {name} "))
        assert f"| {counts[0.0][j]} (" in row, row


def test_the_arm_of_an_init_run_is_reduced_as_it_ran(tmp_path):
    """init's Panda locks its finger joint: the run records it, and the arm identify builds
    from the run has the 7 controlled joints of the run, named as it ran."""
    from hmpc_pin.apps.runfile import load_run, run_robot

    toml = tmp_path / "panda.toml"
    assert main(["init", "panda", "--out", str(toml)]) == 0
    config = load_config(toml)
    config = replace(config, simulation=replace(config.simulation, duration=0.05))
    result = Experiment.from_config(config).run()
    assert result.meta.get("locked_joints")
    robot = run_robot(load_run(result.save(tmp_path / "panda.npz")), None)
    assert robot.nq == 7 and tuple(robot.joint_names) == tuple(result.joint_names)


def test_after_past_the_end_names_the_span_of_a_run_that_starts_late(saved_run, tmp_path,
                                                                      capsys):  # fmt: skip
    """A run whose clock starts at 2 s (a real-time run stamps its own time): the error
    names the span it has, 2 to 7 s (5 s), not 0 to 7 s."""
    result = Result.load(saved_run)
    late = replace(result, t=result.t + 2.0).save(tmp_path / "late.npz")
    code, _out, err, _table = _identify(late, tmp_path, capsys, "--after", "8")
    assert code == 2
    assert "span t = 2 to 7 s, 5 s" in err, err


def test_stuck_joints_and_the_observers_settling_are_left_out_and_said(tmp_path, capsys,
                                                                        monkeypatch):  # fmt: skip
    """On the stick-slip plant under init's bandwidth observer: the note names the joints
    that stuck and the time left out after each, 5 time constants of the observer that
    ran (its error map's spectral radius over every posture of the run, recomputed here
    from the recorded matrix); without that settling the holding torque the observer
    carries biases joint 3's viscous coefficient beyond 3 % (the fit's own error with it
    is the sampling's, ~1 %)."""
    import hmpc_pin.identification.friction as friction

    exp = Experiment.from_config(_friction_config(*FORMS[
        "general bandwidth, model at start (init's)"]))  # fmt: skip
    path = exp.run().save(tmp_path / "run.npz")
    code, out, err, table = _identify(path, tmp_path, capsys)
    assert code == 0, err
    note = next(line for line in out.splitlines() if "stuck" in line)
    run = Result.load(path)
    zero = [i for i in range(3) if np.any((run.dq[1:, i] == 0) & (run.dq[:-1, i] == 0))]
    assert zero and all(f"joint{i + 1}" in note for i in zero)  # at rest over a period
    cY, Ts = np.asarray(run.meta["observer_model"]["matrix"]), 0.01
    rho = 0.0
    for q in run.q:  # backward Euler's error map (I + Ts cY M^-1)^-1
        step = np.linalg.inv(np.eye(3) + Ts * cY @ np.linalg.inv(exp.robot.mass_matrix(q)))
        rho = max(rho, np.max(np.abs(np.linalg.eigvals(step))))
    tau = -Ts / np.log(rho)
    settle, shown = (float(x) for x in re.search(
        r"for ([\d.e+-]+) s after each.*time constant ([\d.e+-]+) s", note).groups())  # fmt: skip
    assert shown == pytest.approx(tau, rel=0.02) and settle == pytest.approx(5 * tau, rel=0.02)
    viscous = np.asarray(table["controller"]["friction"]["viscous"])
    np.testing.assert_allclose(viscous, VISCOUS, rtol=0.03)
    monkeypatch.setattr(friction, "SETTLING_TIME_CONSTANTS", 0.0)
    code, out, err, table = _identify(path, tmp_path, capsys)
    assert abs(table["controller"]["friction"]["viscous"][2] / VISCOUS[2] - 1) > 0.03


def _table_rows(out: str) -> dict[str, list[str]]:
    """identify's printed table: per joint, its cells (viscous, Coulomb, residual RMS,
    samples (effective), cond, moving +/-)."""
    rows = [line for line in out.splitlines() if line.startswith("| ") and "---" not in line]
    return {cells[0]: cells[1:] for cells in (
        [c.strip() for c in line.strip("|").split("|")] for line in rows[1:])}  # fmt: skip


def _runs_of(flags) -> list[tuple[int, int]]:
    """(start, stop) of each run of True, by a plain scan."""
    out, start = [], None
    for k, f in enumerate([*flags, False]):
        if f and start is None:
            start = k
        elif not f and start is not None:
            out.append((start, k))
            start = None
    return out


def _observer_fit_by_hand(result, robot, after=0.5, v0=0.01, confidence=0.95):
    """The observer source's fit written out from its documented equations, in numpy:
    the mid-period velocities' regressors through backward Euler of the recorded
    matrix, the stuck intervals (|q̇| <= max(v0, 4 sigma_v) for 2+ samples; sigma_v from
    second differences) with 5 observer time constants after each (every joint: the NDO
    couples them), feasible GLS over the joints, AR(1) effective samples and Student t
    intervals. Returns per joint (viscous, coulomb, half widths, rms, m, m_e, cond,
    coverage) and the count of samples left out for stuck joints."""
    from scipy.stats import t as student_t

    t, q, dq, d_hat = result.t, result.q, result.dq, result.d_hat
    rec = result.meta["observer_model"]
    cY, Ts = np.asarray(rec["matrix"], float), float(rec["Ts"])
    shift = int(rec.get("model_at", "end") == "start")
    K, n = dq.shape
    v = np.vstack([dq[:1], 0.5 * (dq[1:] + dq[:-1])])
    phi = np.zeros((K, n, 2 * n))
    for i in range(n):
        phi[:, i, 2 * i], phi[:, i, 2 * i + 1] = v[:, i], np.sign(v[:, i])
    g, state, rho = np.zeros_like(phi), np.zeros((n, 2 * n)), 0.0
    for k in range(K):
        L = Ts * cY @ np.linalg.inv(robot.mass_matrix(q[max(k - shift, 0)]))
        if k:
            state = np.linalg.solve(np.eye(n) + L, state + L @ phi[k])
            g[k] = state
        step = np.linalg.inv(np.eye(n) + Ts * cY @ np.linalg.inv(robot.mass_matrix(q[k])))
        rho = max(rho, float(np.max(np.abs(np.linalg.eigvals(step)))))
    tau = -Ts / np.log(rho)
    sigma = 1.4826 * np.median(np.abs(np.diff(dq, 2, axis=0)), axis=0) / np.sqrt(6)
    stuck = np.zeros(K, dtype=bool)
    for i in range(n):
        for s, e in _runs_of(np.abs(dq[:, i]) <= max(v0, 4 * sigma[i])):
            if e - s >= 2:
                stuck |= (t >= t[s]) & (t <= t[min(e, K - 1)] + 5 * tau + 1e-12)
    use = (t >= after - 1e-12) & ~stuck
    keeps = [use & (np.abs(v[:, i]) > v0) for i in range(n)]
    A = [g[keep, i, :] for i, keep in enumerate(keeps)]
    y = [-d_hat[keep, i] for i, keep in enumerate(keeps)]
    theta0 = np.linalg.lstsq(np.vstack(A), np.concatenate(y), rcond=None)[0]
    var = [np.mean((yi - Ai @ theta0) ** 2) for Ai, yi in zip(A, y, strict=True)]
    w = np.concatenate([np.full(len(yi), 1 / s) for yi, s in zip(y, var, strict=True)])
    As, ys = np.vstack(A), np.concatenate(y)
    cov = np.linalg.inv(As.T @ (As * w[:, None]))
    theta = cov @ (As.T @ (w * ys))
    res = [yi - Ai @ theta for Ai, yi in zip(A, y, strict=True)]
    lag1 = [float(r[1:] @ r[:-1] / (r @ r)) for r in res]
    m, p = len(ys), 2 * n
    m_e = m * (1 - max(0.0, np.mean(lag1))) / (1 + max(0.0, np.mean(lag1)))
    scale = sum(r @ r / s for r, s in zip(res, var, strict=True)) / (m - p)
    half = student_t.ppf(0.5 + confidence / 2, max(m_e - p, 1)) * np.sqrt(
        scale * np.diag(cov) * m / m_e)  # fmt: skip
    joints = []
    for i, (keep, r) in enumerate(zip(keeps, res, strict=True)):
        raw = np.column_stack([v[keep, i], np.sign(v[keep, i])])
        m_ei = len(r) * (1 - max(0.0, lag1[i])) / (1 + max(0.0, lag1[i]))
        moving = v[use, i]
        joints.append(dict(
            viscous=theta[2 * i], coulomb=theta[2 * i + 1], half=half[2 * i : 2 * i + 2],
            rms=np.sqrt(np.mean(r**2)), m=len(r), m_e=m_ei,
            cond=np.linalg.cond(raw / np.linalg.norm(raw, axis=0)),
            coverage=(np.mean(moving > 0.05), np.mean(moving < -0.05))))  # fmt: skip
    return joints, int(np.count_nonzero((t >= after - 1e-12) & stuck)), tau


def test_every_figure_of_the_observer_table_is_recomputed_from_the_run(saved_run, tmp_path,
                                                                         capsys):  # fmt: skip
    """identify's table and note on a stick-slip run, each figure recomputed from the
    run's arrays by the documented equations in numpy (the defaults: --after 0.5,
    --velocity-threshold 0.01, 95 %): coefficients, intervals (where given), residual
    RMS, m (m_e), condition, the moving shares, and the samples left out for the stuck
    joints with the observer's time constant."""
    from hmpc_pin.apps.runfile import run_robot

    result = Result.load(saved_run)
    joints, left_out, tau = _observer_fit_by_hand(result, run_robot(result, None))
    code, out, err, table = _identify(saved_run, tmp_path, capsys)
    assert code == 0, err
    rows = _table_rows(out)
    fr = table["controller"]["friction"]
    np.testing.assert_allclose(fr["viscous"], [j["viscous"] for j in joints], rtol=5e-6)
    np.testing.assert_allclose(fr["coulomb"], [j["coulomb"] for j in joints], rtol=5e-6)
    assert left_out > 0 and f"{left_out} samples left out where " in out, out
    assert f"time constant {tau:.3g} s" in out and f"for {5 * tau:.3g} s after each" in out
    for name, j in zip(result.joint_names, joints, strict=True):
        visc, coul, rms, samples, cond, moving = rows[name]
        for cell, value, half in ((visc, j["viscous"], j["half"][0]),
                                  (coul, j["coulomb"], j["half"][1])):  # fmt: skip
            shown = f"{value:.4g} " + (
                "[n/a]" if j["m_e"] - 2 < 10 else f"[{value - half:.4g}, {value + half:.4g}]"
            )
            assert cell == shown, (name, cell, shown)
        assert float(rms) == pytest.approx(j["rms"], rel=5e-3)
        assert samples == f"{j['m']} ({j['m_e']:.0f})"
        assert float(cond) == pytest.approx(j["cond"], rel=5e-3)
        fwd, bwd = j["coverage"]
        assert moving == f"{100 * fwd:.0f} % / {100 * bwd:.0f} %", (moving, fwd, bwd)


def test_every_figure_of_the_thresholds_report_is_recomputed(saved_run, tmp_path, capsys):
    """identify --thresholds with a block that is no whole number of periods (0.333 s at
    10 ms: 33 samples, 0.33 s), the other options at their documented defaults (--after 0,
    false alarm 0.01 per 60 s, safety 1.25, Gumbel): each printed and written figure
    recomputed in numpy from |d_hat| (15 whole blocks of the 501 samples, the Gumbel
    quantile loc - scale ln(-ln p) at p = (1 - 0.01/3)^(0.33/60), floored at the peak)."""
    from scipy.stats import gumbel_r

    out = tmp_path / "collision.toml"
    assert main(["identify", str(saved_run), "--thresholds", "--block", "0.333",
                 "--out", str(out)]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    result = Result.load(saved_run)
    r = np.abs(result.d_hat)
    per_block = 33
    blocks = len(r) // per_block
    maxima = r[: blocks * per_block].reshape(blocks, per_block, 3).max(axis=1)
    p = (1 - 0.01 / 3) ** (0.33 / 60.0)
    expected = []
    for i in range(3):
        loc, scale = gumbel_r.fit(maxima[:, i])
        expected.append(1.25 * max(loc - scale * np.log(-np.log(p)), r[:, i].max()))
    written = out.read_text()
    np.testing.assert_allclose(tomllib.loads(written)["collision"]["threshold"], expected,
                               rtol=1e-5)  # fmt: skip
    assert "false alarm <= 0.01 per 60 s, safety x1.25" in printed, printed
    assert "(gumbel fit of 0.33 s block maxima of |d_hat|), safety factor 1.25" in written
    for name, thr, peak in zip(result.joint_names, expected, r.max(axis=0), strict=True):
        assert f"  {name}: threshold {thr:.4g} N·m (peak |d_hat| in the run {peak:.4g})" in printed
        assert f"#   {name}: threshold {thr:.4g} N·m (run's peak |d_hat| {peak:.4g})" in written


def test_a_config_written_with_the_table_carries_its_comments(saved_run, tmp_path, capsys):
    """--config: the written config starts with the very comment lines of the table
    written alone (where it came from, the intervals, the notes), then loads."""
    code, _out, err, _table = _identify(saved_run, tmp_path, capsys)
    assert code == 0, err
    alone = [x for x in (tmp_path / "friction.toml").read_text().splitlines() if x.startswith("#")]
    merged = tmp_path / "merged.toml"
    assert main(["identify", str(saved_run), "--config", str(CONFIGS / "paper_friction.toml"),
                 "--out", str(merged)]) == 0  # fmt: skip
    lines = merged.read_text().splitlines()
    assert lines[: len(alone)] == alone
    assert load_config(merged).controller.friction is not None


def test_a_file_without_a_record_reads_where_its_configs_observer_takes_its_model(
    tmp_path, capsys
):  # fmt: skip
    """A run written before the observer was recorded, whose config evaluates the
    observer's model at the period's start (``model_at = "start"``): identify rebuilds
    that observer from the config file, so its fit is the one written out in numpy from
    the record the run had (M at q_{k-1}), to rounding; the same with M at q_k differs."""
    from hmpc_pin.apps.runfile import run_robot

    from .conftest import PLANAR3

    text = (CONFIGS / "paper_friction.toml").read_text()
    text = text.replace('model = "planar3"', "urdf = " + json.dumps(str(PLANAR3)))
    implicit = 'discretization = "implicit"'
    text = text.replace(implicit, implicit + '\nmodel_at = "start"')
    text = text.replace("duration = 10.0", "duration = 5.0")
    path = tmp_path / "start.toml"
    path.write_text(text)
    result = Experiment.from_config(load_config(path)).run()
    assert result.meta["observer_model"]["model_at"] == "start"
    robot = run_robot(result, None)
    joints, _, _ = _observer_fit_by_hand(result, robot)
    at_end = replace(result, meta={**result.meta, "observer_model": {
        **result.meta["observer_model"], "model_at": "end"}})  # fmt: skip
    end_joints, _, _ = _observer_fit_by_hand(at_end, robot)
    by_hand = np.array([[j["viscous"], j["coulomb"]] for j in joints])
    at_end_by_hand = np.array([[j["viscous"], j["coulomb"]] for j in end_joints])
    assert np.max(np.abs(at_end_by_hand / by_hand - 1)) > 1e-4  # where M is taken shows
    del result.meta["observer_model"]
    code, _out, err, table = _identify(result.save(tmp_path / "old.npz"), tmp_path, capsys)
    assert code == 0, err
    fr = table["controller"]["friction"]
    np.testing.assert_allclose(np.column_stack([fr["viscous"], fr["coulomb"]]), by_hand,
                               rtol=5e-6)  # fmt: skip


def test_the_default_confidence_is_the_helps_95_percent(saved_run, tmp_path, capsys):
    """Without --confidence the intervals are 95 % ones, as --help says: the table's
    header and the written comment say 95 %, and the table is the one --confidence 0.95
    prints (and not the 0.9 one)."""
    code, out, err, _ = _identify(saved_run, tmp_path, capsys, "--source", "dynamics")
    assert code == 0, err
    assert "viscous [N·m·s/rad] (95 % CI)" in out and "Coulomb [N·m] (95 % CI)" in out, out
    assert "# 95 % confidence intervals" in (tmp_path / "friction.toml").read_text()
    tables = {}
    for level in ("0.95", "0.9"):
        code, printed, err, _ = _identify(saved_run, tmp_path, capsys, "--source", "dynamics",
                                          "--confidence", level)  # fmt: skip
        assert code == 0, err
        tables[level] = [x for x in printed.splitlines() if x.startswith("| joint")]
    ours = [x for x in out.splitlines() if x.startswith("| joint")]
    assert ours == tables["0.95"] != tables["0.9"]


def test_a_block_of_zero_is_refused_naming_it(saved_run, tmp_path, capsys):
    """--block 0 is no duration: one line naming --block, not 'the run is too short'."""
    code, _out, err, table = _identify(saved_run, tmp_path, capsys, "--thresholds",
                                       "--block", "0")  # fmt: skip
    assert code == 2 and table is None
    assert len(err.strip().splitlines()) == 1 and "--block" in err and "too short" not in err
