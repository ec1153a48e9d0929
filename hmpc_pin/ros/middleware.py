"""The middleware settings both nodes start rclpy with, where the user has not set them.

rclpy's middleware (``rmw_fastrtps_cpp``, Fast DDS) reads these environment variables
when a node's context starts; the nodes (:class:`~hmpc_pin.ros.node.RosNode`) set them
in their own process just before, **only where the variable is unset or empty**: a value
the user exported wins.

* ``RMW_FASTRTPS_PUBLICATION_MODE = SYNCHRONOUS``: a sample is sent by the thread that
  publishes it. Asynchronous publication hands every sample to Fast DDS's sender thread
  (a queue, a wake-up, a second thread on the core at every state and every torque);
  rmw_fastrtps publishes synchronously by default since ROS 2 Humble, earlier
  distributions asynchronously: set here, the nodes publish the same way on every
  distribution.

No other setting is applied: on one machine Fast DDS already delivers through shared
memory (its default transports), and the topics' QoS is the nodes' own (best effort
states, reliable commands: :class:`~hmpc_pin.ros.interface.RosArmInterface`).
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

__all__ = ["MIDDLEWARE_DEFAULTS", "apply_middleware_defaults"]

#: The environment variables the nodes set where the user has not (module doc).
MIDDLEWARE_DEFAULTS: dict[str, str] = {"RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS"}


def apply_middleware_defaults(environ: MutableMapping[str, str] = os.environ) -> dict[str, str]:
    """Set each of :data:`MIDDLEWARE_DEFAULTS` in ``environ`` where it is unset or empty;
    returns those set (a user's value is kept)."""
    applied = {}
    for key, value in MIDDLEWARE_DEFAULTS.items():
        if not environ.get(key):
            environ[key] = value
            applied[key] = value
    return applied
