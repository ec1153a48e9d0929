"""The per-joint condensed MPC (Eq 20–26) and its ProxSuite QPs."""

from .condensed import CondensedMPC, JointQPs, StateLimits

__all__ = ["CondensedMPC", "JointQPs", "StateLimits"]
