"""The arm: URDF or robot name → Pinocchio model; dynamics terms; frames; planar 3R IK."""

from .robot import Robot, load_robot

__all__ = ["Robot", "load_robot"]
