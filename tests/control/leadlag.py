"""A control law that exists only in the tests: a lead-lag compensator, written as a user
would write one in their own module (README, "Your own control law"), with its C port
(``leadlag.c`` beside it).

C(s) = K (1 + T1 s) / (1 + T2 s) on the error e = r - y, discretised by Tustin's rule at the
sample time h: v_k = b0 e_k + b1 e_{k-1} - a1 v_{k-1}, u_k = sat(u_off + v_k) with
b0 = K (1 + 2 T1/h) / (1 + 2 T2/h), b1 = K (1 - 2 T1/h) / (1 + 2 T2/h),
a1 = (1 - 2 T2/h) / (1 + 2 T2/h); at rest v = e = 0 and u_off holds the command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from fuzzyservo.control import Field, Law, LawController, indices, kernel
from fuzzyservo.errors import ParameterError
from fuzzyservo.registry import ControllerKind, GainSpec, register_controller

PARAMS = (Field("b0", "1/m", "gain on e_k"), Field("b1", "1/m", "gain on e_{k-1}"),
          Field("a1", "-", "feedback of v_{k-1}"), Field("u_min", "-", "lower limit"),
          Field("u_max", "-", "upper limit"))
STATE = (Field("e_prev", "m", "previous error"), Field("v_prev", "-", "previous output"),
         Field("u_off", "-", "command held at rest"))
GAINS = (Field("k", "1/m", "gain K"), Field("t1", "s", "lead time T1"),
         Field("t2", "s", "lag time T2"))
CONSTANTS = (Field("ts", "s", "sample time h"), Field("u_min", "-", "lower limit"),
             Field("u_max", "-", "upper limit"))
P = indices("LeadLagParams", PARAMS)
S = indices("LeadLagState", STATE)


@kernel(inline=True, error_model="numpy")
def leadlag_step(p: Any, s: Any, r: float, y: float, aux: Any, rd: float,
                 rdd: float) -> float:
    e = r - y
    v = p[P.b0] * e + p[P.b1] * s[S.e_prev] - p[P.a1] * s[S.v_prev]
    u = min(max(s[S.u_off] + v, p[P.u_min]), p[P.u_max])
    s[S.e_prev] = e
    s[S.v_prev] = v
    return u


@kernel(inline=True)
def no_tables(tables: Any) -> float:
    return 0.0


def pack(g: Any, k: Any) -> Any:
    kk, t1, t2 = g.T
    h = float(k[0])
    den = 1.0 + 2.0 * t2 / h
    out = np.empty((g.shape[0], len(PARAMS)))
    out[:, P.b0] = kk * (1.0 + 2.0 * t1 / h) / den
    out[:, P.b1] = kk * (1.0 - 2.0 * t1 / h) / den
    out[:, P.a1] = (1.0 - 2.0 * t2 / h) / den
    out[:, P.u_min] = k[1]
    out[:, P.u_max] = k[2]
    return out


def rest(packed: Any, y0: float, u0: float) -> Any:
    out = np.zeros((packed.shape[0], len(STATE)))
    out[:, S.u_off] = u0
    return out


LEADLAG_LAW = Law(name="leadlag", title="lead-lag", params=PARAMS, state=STATE, gains=GAINS,
                  constants=CONSTANTS, step=leadlag_step, prepare=no_tables, pack=pack,
                  rest=rest, trace="v_prev", c_source=Path(__file__).with_name("leadlag.c"))


@dataclass(frozen=True, slots=True)
class LeadLagState:
    e_prev: float
    v_prev: float
    u_off: float


@dataclass(frozen=True, slots=True, kw_only=True)
class LeadLagController(LawController):
    """Lead-lag compensator [dt, t1, t2 in s, k in 1/m, limits in fractions of the rated
    valve input]."""

    dt: float
    k: float = 0.0
    t1: float = 0.0
    t2: float = 0.0
    u_min: float = -1.0
    u_max: float = 1.0

    law: ClassVar[Law] = LEADLAG_LAW
    state_class: ClassVar[type] = LeadLagState
    gain_names: ClassVar[tuple[str, ...]] = tuple(f.name for f in GAINS)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ParameterError(f"sample time dt must be finite and > 0 s, got {self.dt!r}")
        self.check_gain_rows(self.gain_row()[None, :])

    def initial_state(self, *, u0: float = 0.0) -> LeadLagState:
        return LeadLagState(e_prev=0.0, v_prev=0.0, u_off=u0)

    def law_constants(self) -> Any:
        return np.array([self.dt, self.u_min, self.u_max])


KIND = register_controller(ControllerKind(
    name="leadlag", title="lead-lag", cls=LeadLagController,
    gains=(GainSpec(name="k", unit="1/m", description="gain K", search=(0.1, 100.0)),
           GainSpec(name="t1", unit="s", description="lead time T1", default=0.02,
                    search=(1e-3, 0.5)),
           GainSpec(name="t2", unit="s", description="lag time T2", default=0.002,
                    search=(1e-4, 0.05))),
    options=("u_min", "u_max")), replace=True)
