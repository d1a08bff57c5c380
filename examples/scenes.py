"""Input scenes of the issue-5 studies: length and activation command vs time.

A ``Scene`` gives, vectorised over numpy arrays of times, the muscle length
L(t) [m], the activation command u(t), and their right derivatives (the slope
on [t, t + dt) for small dt: what a master knows at a communication point,
used as the FMU's input derivatives). The three scenes of the
work-precision study (MODEL_NOTES "Experiments"):

* ``passive``: u = 0, L = L0 + 5 mm/s t, to 20 % strain at t = 2 s;
* ``activated``: u = 1 from t = 0, held at L0 until t = 0.5 s, then pulled at
  5 mm/s to 20 % strain at t = 2.5 s;
* ``fast``: a 50 ms activation pulse (u = 1 for 0.10 <= t < 0.15 s) on a
  5 Hz sinusoidal length L0 (1 + 0.05 sin(2 pi 5 t)), t = 0 .. 0.6 s (three
  periods): the CE runs through both force-velocity branches at up to
  |dlambda/dt| = 1.57 1/s while the activation rises and falls.

Switch times are compared with a 1e-9 s tolerance, so a communication point
n h that is a switch time up to rounding counts as on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

L0 = 0.05
SPEED = 0.005
MAX_STRAIN = 0.20
HOLD = 0.5
PULSE = (0.10, 0.15)
FAST_FREQUENCY = 5.0
FAST_AMPLITUDE = 0.05
FAST_END = 0.6
EPS = 1e-9


@dataclass(frozen=True)
class Scene:
    name: str
    t_end: float
    length: Callable
    dlength: Callable
    activation: Callable
    dactivation: Callable
    description: str


def _const(value):
    return lambda t: np.full_like(np.asarray(t, dtype=float), value)


def ramp_scene(name, l_start, l_end, t_start, t_end, activation=0.0, description=""):
    """Length l_start until t_start, then linear to l_end at t_end; a constant command."""
    rate = (l_end - l_start) / (t_end - t_start)

    def length(t):
        t = np.asarray(t, dtype=float)
        return np.where(t < t_start, l_start, l_start + rate * np.clip(t - t_start, 0.0, None))

    def dlength(t):
        t = np.asarray(t, dtype=float)
        return np.where((t >= t_start - EPS) & (t < t_end - EPS), rate, 0.0)

    return Scene(name, t_end, length, dlength, _const(activation), _const(0.0), description)


def passive(l0=L0) -> Scene:
    t_end = MAX_STRAIN * l0 / SPEED
    return ramp_scene("passive", l0, (1 + MAX_STRAIN) * l0, 0.0, t_end, 0.0,
                      "u = 0; pulled from L0 at 5 mm/s to 20 % strain")


def activated(l0=L0) -> Scene:
    t_end = HOLD + MAX_STRAIN * l0 / SPEED
    return ramp_scene("activated", l0, (1 + MAX_STRAIN) * l0, HOLD, t_end, 1.0,
                      "u = 1 from t = 0; held at L0 for 0.5 s, then pulled at 5 mm/s to 20 % strain")


def pulse(t_on, t_off):
    """Command 1 on [t_on, t_off), 0 elsewhere; right derivative 0."""

    def activation(t):
        t = np.asarray(t, dtype=float)
        return np.where((t >= t_on - EPS) & (t < t_off - EPS), 1.0, 0.0)

    return activation


def fast(l0=L0) -> Scene:
    w = 2.0 * np.pi * FAST_FREQUENCY

    def length(t):
        return l0 * (1.0 + FAST_AMPLITUDE * np.sin(w * np.asarray(t, dtype=float)))

    def dlength(t):
        return l0 * FAST_AMPLITUDE * w * np.cos(w * np.asarray(t, dtype=float))

    return Scene("fast", FAST_END, length, dlength, pulse(*PULSE), _const(0.0),
                 "50 ms pulse u = 1 on [0.10, 0.15) s; L = L0 (1 + 0.05 sin(2 pi 5 t)); 0.6 s")


def work_precision_scenes(l0=L0) -> list:
    return [passive(l0), activated(l0), fast(l0)]
