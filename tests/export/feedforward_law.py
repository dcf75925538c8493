"""A control law with feed-forward that exists only in the tests (issue 25): the controller
FMU's inputs ``r_rate`` and ``r_accel`` are tested on it whether or not the package has a
feed-forward kind of its own. Written as a user would write a law (README, "Your own control
law"), with its C port (``feedforward_law.c`` beside it), and registered by the tests that
use it only (tests/export/test_fmu_feedforward.py).

u_k = sat(u_off + (k_v r'_k + k_a r''_k + k_p (r_k - y_k))): proportional feedback plus the
reference's velocity and acceleration scaled; at rest u_off holds the command (bumpless).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from fuzzyservo.control import Field, Law, LawController, indices, kernel
from fuzzyservo.errors import ParameterError
from fuzzyservo.registry import ControllerKind, GainSpec

PARAMS = (Field("kp", "1/m", "gain on the error"), Field("kv", "s/m", "gain on r'"),
          Field("ka", "s2/m", "gain on r''"), Field("u_min", "-", "lower limit"),
          Field("u_max", "-", "upper limit"))
STATE = (Field("u_off", "-", "command held at rest"),)
GAINS = (Field("kp", "1/m", "proportional gain"), Field("kv", "s/m", "velocity feed-forward"),
         Field("ka", "s2/m", "acceleration feed-forward"))
CONSTANTS = (Field("ts", "s", "sample time"), Field("u_min", "-", "lower limit"),
             Field("u_max", "-", "upper limit"))
P = indices("FeedForwardParams", PARAMS)
S = indices("FeedForwardState", STATE)


@kernel(inline=True, error_model="numpy")
def feedforward_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float,
                     rdd: float) -> float:
    v = p[P.kv] * rd + p[P.ka] * rdd + p[P.kp] * (r - y)
    return min(max(s[S.u_off] + v, p[P.u_min]), p[P.u_max])


@kernel(inline=True)
def no_tables(tables: Any) -> float:
    return 0.0


def pack(g: Any, k: Any) -> Any:
    out = np.empty((g.shape[0], len(PARAMS)))
    out[:, P.kp] = g[:, 0]
    out[:, P.kv] = g[:, 1]
    out[:, P.ka] = g[:, 2]
    out[:, P.u_min] = k[1]
    out[:, P.u_max] = k[2]
    return out


def rest(packed: Any, y0: float, u0: float) -> Any:
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.u_off] = u0
    return out


FEEDFORWARD_LAW = Law(name="testff", title="P with feed-forward (tests)", params=PARAMS,
                      state=STATE, gains=GAINS, constants=CONSTANTS, step=feedforward_step,
                      prepare=no_tables, pack=pack, rest=rest, feedforward=True,
                      c_source=Path(__file__).with_name("feedforward_law.c"))


@dataclass(frozen=True, slots=True)
class FeedForwardState:
    u_off: float


@dataclass(frozen=True, slots=True, kw_only=True)
class FeedForwardController(LawController):
    """P control with velocity and acceleration feed-forward [dt in s, kp in 1/m, kv in s/m,
    ka in s²/m, limits in fractions of the rated valve input]."""

    dt: float
    kp: float = 0.0
    kv: float = 0.0
    ka: float = 0.0
    u_min: float = -1.0
    u_max: float = 1.0

    law: ClassVar[Law] = FEEDFORWARD_LAW
    state_class: ClassVar[type] = FeedForwardState
    gain_names: ClassVar[tuple[str, ...]] = tuple(f.name for f in GAINS)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        self.check_gain_rows(self.gain_row()[None, :])

    def initial_state(self, *, u0: float = 0.0) -> FeedForwardState:
        return FeedForwardState(u_off=u0)

    def law_constants(self) -> Any:
        return np.array([self.dt, self.u_min, self.u_max])


KIND = ControllerKind(
    name="testff", title="P with feed-forward (tests)", cls=FeedForwardController,
    gains=(GainSpec(name="kp", unit="1/m", description="proportional gain",
                    search=(0.1, 100.0)),
           GainSpec(name="kv", unit="s/m", description="velocity feed-forward", default=0.0,
                    search=(1e-3, 10.0)),
           GainSpec(name="ka", unit="s2/m", description="acceleration feed-forward",
                    default=0.0, search=(1e-5, 0.1))),
    options=("u_min", "u_max"))
