"""The built-in metrics of one case, from its samples at the communication
points (a failed case has the samples up to where it stopped):

  settling_time      first time after which |ν| stays at or below the
                     campaign's settle_threshold (NaN if it never does);
  peak_nu, final_nu  max |ν| and |ν| at the last sample (√J);
  final_error        |target_error| of the controller at the end (pose or
                     joint error, when the loop is closed);
  energy_drift       max |K − K(0)| (J), meaningful for unforced flights;
  momentum_drift     max |p − p(0)| over the six components;
  control_effort     ∫ |ε| dt of the controller's ε (√J), when closed;
  impulse            per actuator, ∫ |ctrl_k| dt of the controls held (a
                     list; N s for a thruster whose ctrl is its thrust),
                     when the plant has actuators.
"""

from __future__ import annotations

import numpy as np

NAMES = ("settling_time", "peak_nu", "final_nu", "final_error", "energy_drift", "momentum_drift", "control_effort")


def metrics(flight, settle_threshold: float, step: float) -> dict[str, float]:
    n = flight.reached
    if n == 0:
        return {name: float("nan") for name in NAMES}
    speed = np.linalg.norm(flight.nu[:n], axis=1)
    above = np.nonzero(speed > settle_threshold)[0]
    if above.size == 0:
        settling = 0.0
    elif above[-1] + 1 < n:
        settling = float(flight.time[above[-1] + 1])
    else:
        settling = float("nan")
    energy = flight.kinetic_energy[:n]
    momentum = flight.momentum[:n]
    closed = flight.target_error is not None
    effort = float(np.sum(np.linalg.norm(flight.eps[: n - 1], axis=1)) * step) if closed else float("nan")
    impulse = {}
    if flight.ctrl.shape[1]:
        impulse["impulse"] = (np.sum(np.abs(flight.ctrl[: n - 1]), axis=0) * step).tolist()
    return {
        "settling_time": settling,
        "peak_nu": float(np.max(speed)),
        "final_nu": float(speed[-1]),
        "final_error": float(flight.target_error[n - 1]) if closed else float("nan"),
        "energy_drift": float(np.max(np.abs(energy - energy[0]))),
        "momentum_drift": float(np.max(np.abs(momentum - momentum[0]))),
        "control_effort": effort,
        **impulse,
    }
