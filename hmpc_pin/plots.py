"""Figures in the paper's layout: one row per joint, time on the x axis.

Figures are built with ``matplotlib.figure.Figure`` (no pyplot, no global
backend switch), so plotting works headless and never touches the user's
matplotlib state. Every function writes a PNG and returns its path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_disturbance", "plot_error", "plot_overview", "plot_tracking"]


def _rows(n: int, cols: int = 1):
    fig = Figure(figsize=(6 * cols, 2.2 * n + 0.8))
    axes = fig.subplots(n, cols, sharex=True, squeeze=False)
    return fig, axes


def _finish(fig, axes, path, title):
    for ax in axes[-1]:
        ax.set_xlabel("time t [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def _tracking(ax, result, i):
    ax.plot(result.t, result.q_ref[:, i], "k--", lw=1.2, label=f"reference $r_{i + 1}$")
    ax.plot(result.t, result.q[:, i], "C0", lw=1.2, label=f"angle $q_{i + 1}$")
    ax.set_ylabel(f"joint {i + 1} [rad]")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)


def _disturbance(ax, result, i):
    ax.plot(result.t, result.d[:, i], "k", lw=1.2, label=f"true $d_{i + 1}$")
    ax.plot(result.t, result.d_hat[:, i], "C3--", lw=1.2, label=rf"NDO $\hat d_{i + 1}$")
    ax.set_ylabel(f"joint {i + 1} [N·m]")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)


def plot_tracking(result, path, title: str = "") -> Path:
    """Reference vs joint angle, one row per joint (paper Figures 5, 7, 9)."""
    n = result.q.shape[1]
    fig, axes = _rows(n)
    for i in range(n):
        _tracking(axes[i, 0], result, i)
    return _finish(fig, axes, path, title)


def plot_disturbance(result, path, title: str = "") -> Path:
    """True vs NDO-estimated disturbance, one row per joint (paper Figures 4, 6, 8)."""
    n = result.q.shape[1]
    fig, axes = _rows(n)
    for i in range(n):
        _disturbance(axes[i, 0], result, i)
    return _finish(fig, axes, path, title)


def plot_overview(result, path, title: str = "") -> Path:
    """Both side by side: tracking (left) and disturbance estimate (right), one row per joint."""
    n = result.q.shape[1]
    fig, axes = _rows(n, 2)
    for i in range(n):
        _tracking(axes[i, 0], result, i)
        _disturbance(axes[i, 1], result, i)
    return _finish(fig, axes, path, title)


def plot_error(results: dict, path, title: str = "") -> Path:
    """Tracking error |q − r| on a log scale, one row per joint, several runs overlaid.

    Args:
        results: Label → :class:`~hmpc_pin.simulate.Result`, e.g.
            ``{"with NDO": r1, "without NDO": r2}``.
    """
    first = next(iter(results.values()))
    n = first.q.shape[1]
    fig, axes = _rows(n)
    for i in range(n):
        ax = axes[i, 0]
        for k, (label, r) in enumerate(results.items()):
            e = np.abs(r.error[:, i])
            ax.semilogy(r.t, np.maximum(e, 1e-9), f"C{k}", lw=1.0, label=label)
        ax.axhline(0.01, color="k", ls=":", lw=0.8, label="0.01 rad")
        ax.set_ylabel(f"|e{i + 1}| [rad]")
        ax.set_ylim(1e-7, None)
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3, which="both")
    return _finish(fig, axes, path, title)
