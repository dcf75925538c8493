"""The sweep spec: what a robustness sweep runs, read from a TOML file and validated in full
before anything runs.

A sweep runs every controller of the spec on every *point*: a plant (a parameter set with some
fields changed), a transport delay, a reference amplitude and a sensor-noise level. Points are
the full factorial of the ``grid`` variations, each repeated ``samples`` times with fresh draws
of the ``random`` variations (uniform, log-uniform, normal, log-normal, each optionally
truncated to bounds). Point ``i`` is grid cell ``i // samples``, draw ``i % samples``.

Example (``fuzzyservo sweep --example`` prints a complete one)::

    [sweep]
    plant = "linear"          # a registered plant
    duration = 5.0            # [s]
    samples = 100             # random draws per grid cell
    seed = 1

    [reference]
    spec = "step:0.1"         # as ``fuzzyservo simulate --reference``

    [[controllers]]
    label = "tuned stfpi"
    gains = "linear-stfpi.toml"    # a gains file (next to the spec, or shipped), or a table

    [[vary]]
    name = "load.mass"        # any group.field of the parameters, or delay, amplitude, noise_std
    relative = true           # values are factors of the nominal value
    grid = [0.5, 1.0, 2.0]

    [[vary]]
    name = "fluid.oil_bulk_modulus"
    relative = true
    distribution = "log-uniform"
    low = 0.5
    high = 2.0

Everything a result depends on is in :meth:`SweepSpec.canonical` (gains resolved to numbers,
files by their SHA-256); its digest names the sweep in the manifest, so that ``--resume`` never
mixes the rows of two different sweeps.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from scipy.special import ndtr

from .._io import parse_toml, read_text, sha256_file
from ..errors import InputError, ParameterError
from ..paper.published import SET_NAMES, named_set
from ..plant import ServoParams, allowed_names, with_overrides
from ..registry import controller_kind, controller_names, plant_kind, plant_names
from ..registry.plants import DEFAULT_SUBSTEP
from ..sim.closed_loop import MAX_RK4_STEPS, time_grid
from ..sim.disturbances import LoadStep, parse_load_force
from ..sim.references import Step, parse_reference

__all__ = [
    "DISTRIBUTIONS",
    "LOG_TAIL_SCHEME",
    "MAX_POINTS",
    "SAMPLING_SCHEME",
    "SPECIAL_NAMES",
    "UNRECORDED_SCHEME",
    "ControllerEntry",
    "SweepSpec",
    "Variation",
    "canonical_digest",
    "load_spec",
    "parse_spec",
]

#: Names a variation may take besides ``group.field`` parameters: the transport delay [s],
#: the step amplitude [m], the standard deviation of the sensor noise [m] and the force F
#: [N] of the run's load-force step (``[sweep] load_force = "step:F:T"``).
SPECIAL_NAMES: tuple[str, ...] = ("delay", "amplitude", "noise_std", "load_force_step")

#: ``load_force`` is a friendlier name for the load force F_L [N] (``load.external_force``).
_ALIASES = {"load_force": "load.external_force"}

#: Random distributions and the keys each takes (``low``/``high`` are bounds for the
#: unbounded ones: the draw is truncated to them, by inverse CDF, never clipped).
DISTRIBUTIONS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # name: (required keys, optional keys)
    "uniform": (("low", "high"), ()),
    "log-uniform": (("low", "high"), ()),
    "normal": (("mean", "std"), ("low", "high")),
    "log-normal": (("median", "sigma"), ("low", "high")),
}

#: Most points a sweep may have (runs = points x controllers).
MAX_POINTS = 100_000_000
#: Most draws per grid cell (a draw's counter holds the cell and the draw in 32 bits each).
MAX_SAMPLES = 2**32 - 1

#: Points per chunk by default: a chunk is one task, one Parquet file and the unit of resume.
DEFAULT_CHUNK = 1000
#: Version of the way points are drawn (``sampling.py``: the counter-based generator, the
#: stream numbers, the inverse CDFs). It is part of the canonical spec, so its digest, so a
#: sweep drawn by another scheme is never resumed into (its rows would mix two draws).
SAMPLING_SCHEME = 1
#: The scheme of a spec with a bounded normal or log-normal so far in a tail (beyond about
#: 37 standard deviations) that scheme 1 put every draw on a bound: its draws are now exact
#: (in logarithms, ``sampling._tail_in_logs``), and a folder scheme 1 drew for such a spec
#: is never resumed into. Every other spec draws the same bits as in scheme 1, and keeps it.
LOG_TAIL_SCHEME = 2
#: The scheme of a manifest that names none: written before the scheme was recorded, whose
#: draws are scheme 1's.
UNRECORDED_SCHEME = 1

_SWEEP_KEYS = {"name", "plant", "param_set", "start", "ts", "duration", "substep", "samples",
               "seed", "chunk", "delay", "noise_std", "load_force"}
_TOP_KEYS = {"sweep", "reference", "overrides", "controllers", "vary"}
_CTL_KEYS = {"label", "controller", "gains", "options", "du_system", "alpha_system",
             "no_rule_value"}
_VARY_KEYS = {"name", "relative", "grid", "distribution", "low", "high", "mean", "std",
              "median", "sigma"}
#: Parameters that do nothing in the simulated loop: the sweep's own ``noise_std`` and
#: ``delay`` are the sensor noise and the transport delay (``delay = "hose"`` reads
#: ``delay.transport_delay``, which may be overridden but not varied).
_INERT = {"transducer.noise_std": "noise_std", "delay.transport_delay": "delay"}


def _bad(where: str, what: str) -> ParameterError:
    return ParameterError(f"{where}: {what}")


def _number(where: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _bad(where, f"must be a finite number, got {value!r}")
    v = float(value)
    if positive and not v > 0.0:
        raise _bad(where, f"must be > 0, got {value!r}")
    if nonneg and not v >= 0.0:
        raise _bad(where, f"must be >= 0, got {value!r}")
    return v


def _integer(where: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise _bad(where, f"must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _unknown(where: str, table: Mapping[str, Any], allowed: set[str]) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        raise _bad(where, f"unknown key {extra[0]!r}; allowed: {', '.join(sorted(allowed))}")


@dataclass(frozen=True, slots=True, kw_only=True)
class Variation:
    """One quantity a sweep varies.

    ``values`` for a grid; otherwise ``distribution`` with its numbers in ``args``. With
    ``relative`` the values (and the distribution's numbers) are factors of the nominal value.
    """

    name: str  #: ``group.field``, ``delay`` [s], ``amplitude`` [m] or ``noise_std`` [m]
    relative: bool = False  #: values are factors of the nominal value [-]
    values: tuple[float, ...] = ()  #: grid values (SI, or factors)
    distribution: str = ""  #: one of :data:`DISTRIBUTIONS` for a random variation
    args: tuple[tuple[str, float], ...] = ()  #: the distribution's numbers, by key

    @property
    def is_grid(self) -> bool:
        """Whether the variation is a grid (else random)."""
        return bool(self.values)

    def arg(self, key: str, default: float = math.nan) -> float:
        """A number of the distribution (``default`` when not given)."""
        return dict(self.args).get(key, default)

    def record(self) -> dict[str, Any]:
        """As a canonical JSON-able dict."""
        out: dict[str, Any] = {"name": self.name, "relative": self.relative}
        if self.values:
            out["grid"] = list(self.values)
        else:
            out["distribution"] = self.distribution
            out.update(dict(self.args))
        return out


@dataclass(frozen=True, slots=True, kw_only=True)
class ControllerEntry:
    """One controller of a sweep, built through the registry."""

    label: str  #: unique label in the dataset's ``controller`` column
    controller: str  #: registered controller name
    gains: tuple[tuple[str, float], ...]  #: every gain of the kind [gain units]
    options: tuple[tuple[str, Any], ...] = ()  #: controller options the kind takes
    systems: tuple[tuple[str, str], ...] = ()  #: (role, file) of fuzzy systems from files
    no_rule_value: float | None = None  #: value of a file system where no rule fires
    source: str = ""  #: the gains file the gains came from, "" when inline
    digests: tuple[tuple[str, str], ...] = ()  #: (file, sha256) of every file read

    def record(self) -> dict[str, Any]:
        """As a canonical JSON-able dict."""
        return {"label": self.label, "controller": self.controller,
                "gains": dict(self.gains), "options": dict(self.options),
                "systems": dict(self.systems), "no_rule_value": self.no_rule_value,
                "files": dict(self.digests)}

    def build(self, ts: float) -> Any:
        """The controller at sample time ``ts`` [s]."""
        from ..formats import read_system
        from ..fuzzy.loop import loop_system
        from ..registry import default_systems

        kind = controller_kind(self.controller)
        systems: dict[str, Any] | None = None
        if self.systems:
            systems = {role: loop_system(read_system(path), source=path,
                                         no_rule_value=self.no_rule_value)
                       for role, path in self.systems}
            for role, default in default_systems(
                    tuple(r for r in kind.systems if r not in systems)).items():
                systems[role] = default
        return kind.build(dict(self.gains), dt=ts, options=dict(self.options), systems=systems)


@dataclass(frozen=True, slots=True, kw_only=True)
class SweepSpec:
    """A validated sweep (see the module docstring for the file)."""

    name: str = "sweep"  #: a title for the report
    plant: str = "linear"  #: registered plant name
    param_set: str = "paper"  #: named parameter set
    overrides: tuple[tuple[str, float], ...] = ()  #: fixed overrides of the set [SI]
    start: float = 0.5  #: start position, fraction of the stroke [-]
    ts: float = 1e-3  #: controller sample time [s]
    duration: float = 5.0  #: simulated time per run [s]
    substep: float = DEFAULT_SUBSTEP  #: RK4 step bound of the nonlinear plant [s]
    reference: str = "step:0.1"  #: reference offset from the start (simulate's syntax) [m]
    delay: float = 0.0  #: nominal transport delay [s]
    noise_std: float = 0.0  #: nominal sensor-noise standard deviation [m]
    #: load-force disturbance as ``simulate --load-force`` takes it (a CSV by its absolute
    #: path), added to load.external_force [N, s]; "" none
    load_force: str = ""
    samples: int = 1  #: random draws per grid cell
    seed: int = 0  #: seed of every random draw
    chunk: int = DEFAULT_CHUNK  #: points per chunk
    controllers: tuple[ControllerEntry, ...] = ()  #: the controllers compared
    vary: tuple[Variation, ...] = ()  #: what varies
    base_dir: str = "."  #: folder relative file names were resolved against
    params_nominal: ServoParams | None = field(default=None, compare=False)  #: resolved set

    # ---- derived sizes -------------------------------------------------------------------
    @property
    def grid(self) -> tuple[Variation, ...]:
        """The grid variations, in spec order (the first varies slowest)."""
        return tuple(v for v in self.vary if v.is_grid)

    @property
    def random(self) -> tuple[Variation, ...]:
        """The random variations, in spec order."""
        return tuple(v for v in self.vary if not v.is_grid)

    @property
    def n_cells(self) -> int:
        """Grid cells (1 without grid variations)."""
        return math.prod(len(v.values) for v in self.grid)

    @property
    def n_points(self) -> int:
        """Points: grid cells x samples."""
        return self.n_cells * self.samples

    @property
    def n_runs(self) -> int:
        """Runs: points x controllers."""
        return self.n_points * len(self.controllers)

    @property
    def n_chunks(self) -> int:
        """Chunks of :attr:`chunk` points."""
        return -(-self.n_points // self.chunk)

    def chunk_range(self, c: int) -> tuple[int, int]:
        """Points [lo, hi) of chunk ``c``."""
        lo = c * self.chunk
        return lo, min(self.n_points, lo + self.chunk)

    @property
    def nominal(self) -> ServoParams:
        """The parameter set with the fixed overrides applied."""
        if self.params_nominal is not None:
            return self.params_nominal
        base = named_set(self.param_set)
        return with_overrides(base, dict(self.overrides)) if self.overrides else base

    @property
    def step_amplitude(self) -> float | None:
        """The reference's step amplitude [m] (None when the reference is not a step)."""
        ref = parse_reference(self.reference)
        return float(ref.amplitude) if isinstance(ref, Step) else None

    @property
    def load_step(self) -> LoadStep | None:
        """The load force when it is a step (None: none, or another profile)."""
        prof = parse_load_force(self.load_force)
        return prof if isinstance(prof, LoadStep) else None

    def nominal_value(self, name: str) -> float:
        """The nominal value of a varied quantity (SI)."""
        if name == "load_force_step":
            step = self.load_step
            assert step is not None
            return float(step.force)
        if name == "delay":
            return self.delay
        if name == "noise_std":
            return self.noise_std
        if name == "amplitude":
            amp = self.step_amplitude
            assert amp is not None
            return amp
        group, fname = name.split(".", 1)
        return float(getattr(getattr(self.nominal, group), fname))

    def canonical(self) -> dict[str, Any]:
        """Everything the results depend on, JSON-able, in a fixed order (the load force only
        when there is one, so that the digest of a sweep without is that of before)."""
        out = {
            "name": self.name, "plant": self.plant, "param_set": self.param_set,
            "overrides": dict(self.overrides), "start": self.start, "ts": self.ts,
            "duration": self.duration, "substep": self.substep, "reference": self.reference,
            "delay": self.delay, "noise_std": self.noise_std, "samples": self.samples,
            "seed": self.seed, "chunk": self.chunk,
            "controllers": [c.record() for c in self.controllers],
            "vary": [v.record() for v in self.vary],
            "sampling": self.sampling_scheme,
        }
        if self.load_force:
            out["load_force"] = self.load_force
            if self.load_force.lower().endswith(".csv"):
                out["load_force_sha256"] = sha256_file(Path(self.load_force))
        return out

    @property
    def sampling_scheme(self) -> int:
        """The scheme its points are drawn by: :data:`LOG_TAIL_SCHEME` when a variation is
        drawn in logarithms, else :data:`SAMPLING_SCHEME`."""
        return LOG_TAIL_SCHEME if any(in_log_tail(v) for v in self.random) \
            else SAMPLING_SCHEME

    @classmethod
    def from_canonical(cls, doc: Mapping[str, Any]) -> SweepSpec:
        """The spec a manifest records (:meth:`canonical`): the same digest, files named by
        the absolute paths they were read from."""
        entries = tuple(
            ControllerEntry(label=c["label"], controller=c["controller"],
                            gains=tuple((k, float(v)) for k, v in c["gains"].items()),
                            options=tuple(c["options"].items()),
                            systems=tuple(c["systems"].items()),
                            no_rule_value=c["no_rule_value"],
                            digests=tuple(c["files"].items()))
            for c in doc["controllers"])
        vary = []
        for v in doc["vary"]:
            if "grid" in v:
                vary.append(Variation(name=v["name"], relative=v["relative"],
                                      values=tuple(float(x) for x in v["grid"])))
            else:
                args = tuple((k, float(x)) for k, x in v.items()
                             if k not in ("name", "relative", "distribution"))
                vary.append(Variation(name=v["name"], relative=v["relative"],
                                      distribution=v["distribution"], args=args))
        return cls(name=doc["name"], plant=doc["plant"], param_set=doc["param_set"],
                   overrides=tuple((k, float(v)) for k, v in doc["overrides"].items()),
                   start=doc["start"], ts=doc["ts"], duration=doc["duration"],
                   substep=doc["substep"], reference=doc["reference"], delay=doc["delay"],
                   noise_std=doc["noise_std"], load_force=doc.get("load_force", ""),
                   samples=doc["samples"], seed=doc["seed"],
                   chunk=doc["chunk"], controllers=entries, vary=tuple(vary))

    @property
    def digest(self) -> str:
        """SHA-256 of :meth:`canonical` (names the sweep in its manifest)."""
        return canonical_digest(self.canonical())


def canonical_digest(doc: Mapping[str, Any]) -> str:
    """SHA-256 of a canonical spec (:meth:`SweepSpec.canonical`) as sorted compact JSON."""
    text = json.dumps(doc, sort_keys=True, allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def load_spec(path: str | Path) -> SweepSpec:
    """Read and validate a sweep spec file (TOML).

    Raises
    ------
    InputError
        The file cannot be read or is not TOML.
    ParameterError
        Anything invalid in it; the message names the key and what is allowed.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"sweep spec {str(path)!r} is a directory; give a .toml file")
    text = read_text(path, "sweep spec")
    doc = parse_toml(text, f"sweep spec {str(path)!r}")  # nesting bounded, one-line errors
    try:
        return parse_spec(doc, base_dir=path.parent)
    except ParameterError as exc:
        raise ParameterError(f"{str(path)!r}: {exc}") from None


def _resolve_file(name: str, base_dir: Path, where: str, *, shipped: str | None = None) -> Path:
    p = Path(name)
    cand = p if p.is_absolute() else base_dir / p
    if cand.is_file():
        return cand.resolve()
    if shipped is not None and not p.is_absolute() and len(p.parts) == 1:
        from importlib import resources

        data = Path(str(resources.files("fuzzyservo") / "data" / shipped / p.name))
        if data.is_file():
            return data
    raise _bad(where, f"no file {name!r} (relative names are read next to the spec"
                      + (", then among the shipped ones" if shipped else "") + ")")


def _controller(i: int, table: Any, base_dir: Path, ts: float) -> ControllerEntry:
    where = f"controllers[{i}]"
    if not isinstance(table, dict):
        raise _bad(where, "must be a table ([[controllers]])")
    _unknown(where, table, _CTL_KEYS)
    gains_in = table.get("gains")
    digests: list[tuple[str, str]] = []
    source = ""
    gf_systems: tuple[tuple[str, str, str], ...] | None = None
    if isinstance(gains_in, str):
        from ..files import read_gains_file

        path = _resolve_file(gains_in, base_dir, f"{where}.gains", shipped="gains")
        try:
            gf = read_gains_file(path)
        except InputError as exc:
            raise _bad(f"{where}.gains", str(exc)) from None
        if "controller" in table and table["controller"] != gf.controller:
            raise _bad(f"{where}.controller", f"{table['controller']!r} disagrees with the "
                                              f"gains file's {gf.controller!r}")
        if gf.ts is not None and gf.ts != ts:
            raise _bad(f"{where}.gains", f"{str(path)!r} was tuned at ts = {gf.ts!r} s, the "
                                         f"sweep runs at ts = {ts!r} s (the fuzzy PIs' kde is "
                                         f"per sample): set [sweep] ts or use other gains")
        name = gf.controller
        gains = dict(gf.gains)
        source = str(path)
        gf_systems = gf.tuned.setup.systems if gf.tuned is not None else None
        digests.append(("gains", sha256_file(path)))
    elif isinstance(gains_in, dict):
        name = str(table.get("controller"))
        if name not in controller_names():
            raise _bad(f"{where}.controller", f"must be one of {', '.join(controller_names())}, "
                                              f"got {table.get('controller')!r}")
        gains = {str(k): _number(f"{where}.gains.{k}", v) for k, v in gains_in.items()}
    else:
        raise _bad(f"{where}.gains", f"give a gains file name or a table of gains, got "
                                     f"{gains_in!r}")
    kind = controller_kind(name)
    checked = kind.check_gains(gains, where=f"{where}.gains: ")
    label = table.get("label", name)
    if not isinstance(label, str) or not label.strip():
        raise _bad(f"{where}.label", f"must be a non-empty string, got {label!r}")
    options = table.get("options", {})
    if not isinstance(options, dict):
        raise _bad(f"{where}.options", f"must be a table, got {options!r}")
    bad = [o for o in options if o not in kind.option_names]
    if bad:
        raise _bad(f"{where}.options", f"controller {name} takes no option {bad[0]!r}; its "
                                       f"options: {', '.join(kind.option_names) or 'none'}")
    bad = [o for o in options if not kind.option(o).offered]
    if bad:  # every run must replay with fuzzyservo simulate, which has no flag for it
        raise _bad(f"{where}.options", f"{bad[0]!r} cannot be set in a sweep (fuzzyservo "
                                       f"simulate could not replay its runs); allowed: "
                                       f"{', '.join(o.name for o in kind.options if o.offered)}")
    for key, value in options.items():  # the values the declaration allows (kept as given)
        kind.option(key).parse(value, f"{where}.options: ")
    systems: list[tuple[str, str]] = []
    for role in ("du", "alpha"):
        key = f"{role}_system"
        if key not in table:
            continue
        if role not in kind.systems:
            raise _bad(f"{where}.{key}", f"controller {name} has no {role} system")
        if not isinstance(table[key], str):
            raise _bad(f"{where}.{key}", f"must be a file name, got {table[key]!r}")
        path = _resolve_file(table[key], base_dir, f"{where}.{key}", shipped="systems")
        systems.append((role, str(path)))
        digests.append((key, sha256_file(path)))
    nrv = table.get("no_rule_value")
    if nrv is not None:
        nrv = _number(f"{where}.no_rule_value", nrv)
    entry = ControllerEntry(label=label.strip(), controller=name,
                            gains=tuple(checked.items()),
                            options=tuple(sorted(options.items())), systems=tuple(systems),
                            no_rule_value=nrv, source=source, digests=tuple(digests))
    ctl = entry.build(ts)  # options and systems are checked by building once
    recorded = {} if gf_systems is None else {role: d for role, _src, d in gf_systems}
    if recorded:
        from ..formats import read_system
        from ..fuzzy.loop import loop_system, system_digest
        from ..paper import paper_fuzzy_system

        given = {role: loop_system(read_system(path), source=path, no_rule_value=nrv).digest
                 for role, path in systems}
        for role, digest in recorded.items():
            if given.get(role, system_digest(paper_fuzzy_system(role))) != digest:
                src = {r: src for r, src, _ in gf_systems or ()}[role]
                raise _bad(f"{where}.gains", f"the gains file was tuned with another {role} "
                                             f"system ({src!r}); give it as {role}_system")
    del ctl
    return entry


#: A parameter's own range check (plant/params.py: sign and finiteness, which depend on
#: its value alone). Checks relating it to another parameter (rod < bore) are not: another
#: varied parameter may satisfy them, so they are left to each point.
_OWN_RANGE = "{name} must be (?:> 0|>= 0|a finite number), got "
#: Varied parameters that move the stroke or the transducer's resolution, against which the
#: reference is checked (with one of them varied, each point is checked alone).
_STROKE_NAMES = ("cylinder.stroke", "transducer.resolution")


def _out_of_range(spec: SweepSpec, name: str, relative: bool, value: float) -> str | None:
    """Why ``value`` (a factor when ``relative``) is outside the range of the parameter
    ``name`` on its own, or None (also for the special names, checked elsewhere)."""
    if "." not in name:
        return None
    si = spec.nominal_value(name) * value if relative else value
    try:
        with_overrides(spec.nominal, {name: si})
    except ParameterError as exc:
        if re.match(_OWN_RANGE.format(name=re.escape(name)), str(exc)):
            return str(exc)
    return None


def _variation(i: int, table: Any, spec: SweepSpec) -> Variation:
    where = f"vary[{i}]"
    if not isinstance(table, dict):
        raise _bad(where, "must be a table ([[vary]])")
    _unknown(where, table, _VARY_KEYS)
    name = table.get("name")
    if not isinstance(name, str):
        raise _bad(f"{where}.name", f"must be a string, got {name!r}")
    name = _ALIASES.get(name, name)
    if name in _INERT:
        raise _bad(f"{where}.name", f"{name} does nothing in the loop: vary {_INERT[name]} "
                                    f"instead")
    if name not in SPECIAL_NAMES and name not in allowed_names():
        raise _bad(f"{where}.name", f"{name!r} is neither delay, amplitude, noise_std, "
                                    f"load_force, load_force_step nor a parameter "
                                    f"group.field (e.g. load.mass)")
    if name == "load_force_step" and spec.load_step is None:
        raise _bad(where, f"load_force_step varies the force F [N] of a load-force step: "
                          f"set [sweep] load_force = \"step:F:T\" (it is "
                          f"{spec.load_force!r})")
    relative = table.get("relative", False)
    if not isinstance(relative, bool):
        raise _bad(f"{where}.relative", f"must be true or false, got {relative!r}")
    if relative and name in ("delay", "noise_std"):
        raise _bad(f"{where}.relative", f"{name} is varied in absolute SI values (its nominal "
                                        f"may be 0): drop 'relative'")
    if name == "amplitude" and spec.step_amplitude is None:
        raise _bad(where, f"amplitude varies a step reference; the reference is "
                          f"{spec.reference!r}")
    if name == "load.external_force" and not plant_kind(spec.plant).force_input:
        raise _bad(where, f"the {spec.plant} plant has no load-force input; use the "
                          f"nonlinear plant")
    if relative and spec.nominal_value(name) == 0.0:
        raise _bad(f"{where}.relative", f"the nominal {name} is 0: give absolute values")
    if "grid" in table:
        if "distribution" in table or any(k in table for k in DISTRIBUTIONS["normal"][0]
                                          + DISTRIBUTIONS["log-normal"][0] + ("low", "high")):
            raise _bad(where, "give either grid = [...] or a distribution with its numbers")
        grid = table["grid"]
        if not isinstance(grid, list) or not grid:
            raise _bad(f"{where}.grid", f"must be a non-empty list of numbers, got {grid!r}")
        values = tuple(_number(f"{where}.grid", v) for v in grid)
        if name in ("delay", "noise_std") and min(values) < 0.0:
            raise _bad(f"{where}.grid", f"{name} must be >= 0, got {min(values)!r}")
        if len(set(values)) != len(values):
            raise _bad(f"{where}.grid", "has a value twice")
        for v in values:
            why = _out_of_range(spec, name, relative, v)
            if why is not None:
                raise _bad(f"{where}.grid", f"{v!r} is not a value {name} may take ({why})")
        return Variation(name=name, relative=relative, values=values)
    dist = table.get("distribution")
    if dist not in DISTRIBUTIONS:
        raise _bad(f"{where}.distribution",
                   f"must be one of {', '.join(DISTRIBUTIONS)} (or give grid = [...]), "
                   f"got {dist!r}")
    required, optional = DISTRIBUTIONS[dist]
    args: dict[str, float] = {}
    for key in (*required, *optional):
        if key in table:
            args[key] = _number(f"{where}.{key}", table[key])
        elif key in required:
            raise _bad(where, f"a {dist} distribution needs {' and '.join(required)}")
    extra = [k for k in ("low", "high", "mean", "std", "median", "sigma")
             if k in table and k not in required + optional]
    if extra:
        raise _bad(f"{where}.{extra[0]}", f"does not apply to a {dist} distribution (it takes "
                                          f"{', '.join(required + optional)})")
    lo, hi = args.get("low", -math.inf), args.get("high", math.inf)
    if not lo < hi:
        raise _bad(where, f"needs low < high, got {lo!r} and {hi!r}")
    if name in ("delay", "noise_std") and dist in ("uniform", "normal") and not lo >= 0.0:
        raise _bad(f"{where}.low", f"{name} must be >= 0: give low >= 0 (a {dist} "
                                   f"distribution's draws are truncated to [low, high])")
    if dist == "log-uniform" and not lo > 0.0:
        raise _bad(f"{where}.low", f"a log-uniform distribution needs low > 0, got {lo!r}")
    if dist == "normal" and not args["std"] > 0.0:
        raise _bad(f"{where}.std", f"must be > 0, got {args['std']!r}")
    if dist == "log-normal":
        if not args["median"] > 0.0:
            raise _bad(f"{where}.median", f"must be > 0, got {args['median']!r}")
        if not args["sigma"] > 0.0:
            raise _bad(f"{where}.sigma", f"must be > 0, got {args['sigma']!r}")
    for key, bound, other in (("low", lo, hi), ("high", hi, lo)):
        if math.isfinite(bound):  # draws come as close to a bound as the doubles allow
            why = _out_of_range(spec, name, relative, math.nextafter(bound, other))
            if why is not None:
                raise _bad(f"{where}.{key}", f"{bound!r} lets draws take values {name} may "
                                             f"not take ({why}); give bounds inside its "
                                             f"range")
    return Variation(name=name, relative=relative, distribution=str(dist),
                     args=tuple(args.items()))


def parse_spec(doc: Mapping[str, Any], *, base_dir: str | Path = ".") -> SweepSpec:
    """Validate a parsed spec (the TOML's tables); relative file names are resolved against
    ``base_dir``.

    Raises
    ------
    ParameterError
        Anything invalid; the message names the key and what is allowed.
    """
    base = Path(base_dir)
    _unknown("spec", doc, _TOP_KEYS)
    sw = doc.get("sweep", {})
    if not isinstance(sw, dict):
        raise _bad("sweep", "must be a table ([sweep])")
    _unknown("sweep", sw, _SWEEP_KEYS)
    plant = sw.get("plant", "linear")
    if plant not in plant_names():
        raise _bad("sweep.plant", f"must be one of {', '.join(plant_names())}, got {plant!r}")
    param_set = sw.get("param_set", "paper")
    if param_set not in SET_NAMES:
        raise _bad("sweep.param_set", f"must be one of {', '.join(SET_NAMES)}, "
                                      f"got {param_set!r}")
    ov = doc.get("overrides", {})
    if not isinstance(ov, dict):
        raise _bad("overrides", "must be a table of \"group.field\" = value")
    overrides: dict[str, float] = {}
    for k, v in ov.items():
        if isinstance(v, dict):  # [overrides.load] mass = ... (TOML nesting of dotted keys)
            for f, x in v.items():
                overrides[f"{k}.{f}"] = _number(f"overrides.{k}.{f}", x)
        else:
            overrides[str(k)] = _number(f"overrides.{k}", v)
    if "transducer.noise_std" in overrides:
        raise _bad("overrides", "transducer.noise_std does nothing in the loop: set [sweep] "
                                "noise_std or vary noise_std")
    params = with_overrides(named_set(param_set), overrides) if overrides \
        else named_set(param_set)
    start = _number("sweep.start", sw.get("start", 0.5))
    if not 0.0 < start < 1.0:
        raise _bad("sweep.start", f"must be a fraction of the stroke in (0, 1), got {start!r}")
    ts = _number("sweep.ts", sw.get("ts", 1e-3), positive=True)
    duration = _number("sweep.duration", sw.get("duration", 5.0), positive=True)
    n_samples = time_grid(duration, ts).size
    substep = _number("sweep.substep", sw.get("substep", DEFAULT_SUBSTEP), positive=True)
    if plant_kind(plant).force_input and n_samples * ts / substep > MAX_RK4_STEPS:
        raise _bad("sweep.substep", f"{substep!r} s gives more than {MAX_RK4_STEPS:.0e} RK4 "
                                    f"steps per run")
    delay_in = sw.get("delay", 0.0)
    if isinstance(delay_in, str) and delay_in.strip().lower() == "hose":
        delay = float(params.delay.transport_delay)
    else:
        delay = _number("sweep.delay", delay_in, nonneg=True)
    noise = _number("sweep.noise_std", sw.get("noise_std", 0.0), nonneg=True)
    load_force = sw.get("load_force", "")
    if not isinstance(load_force, str):
        raise _bad("sweep.load_force", f"must be text as simulate --load-force takes it "
                                       f"(step:F[:T], pwl:T0:F0,..., FILE.csv), got "
                                       f"{load_force!r}")
    if load_force.strip().lower().endswith(".csv"):
        load_force = str(_resolve_file(load_force.strip(), base, "sweep.load_force"))
    try:
        parse_load_force(load_force)
    except InputError as exc:
        raise _bad("sweep.load_force", str(exc)) from None
    ref = doc.get("reference", {})
    if not isinstance(ref, dict):
        raise _bad("reference", "must be a table with spec = \"step:0.1\" (simulate's syntax)")
    _unknown("reference", ref, {"spec"})
    ref_spec = ref.get("spec", "step:0.1")
    if not isinstance(ref_spec, str):
        raise _bad("reference.spec", f"must be a string such as \"step:0.1\", got {ref_spec!r}")
    try:
        parse_reference(ref_spec)
    except InputError as exc:
        raise _bad("reference.spec", str(exc)) from None
    spec = SweepSpec(
        name=str(sw.get("name", "sweep")), plant=plant, param_set=param_set,
        overrides=tuple(overrides.items()), start=start, ts=ts, duration=duration,
        substep=substep, reference=ref_spec, delay=delay, noise_std=noise,
        load_force=load_force.strip(), samples=_integer("sweep.samples", sw.get("samples", 1), 1,
                         min(MAX_POINTS, MAX_SAMPLES)),
        seed=_integer("sweep.seed", sw.get("seed", 0), 0, 2**63 - 1),
        chunk=_integer("sweep.chunk", sw.get("chunk", DEFAULT_CHUNK), 1, 1_000_000),
        base_dir=str(base), params_nominal=params)
    ctls = doc.get("controllers")
    if not isinstance(ctls, list) or not ctls:
        raise _bad("controllers", "give at least one [[controllers]] table")
    entries = tuple(_controller(i, t, base, ts) for i, t in enumerate(ctls))
    labels = [e.label for e in entries]
    dup = next((x for x in labels if labels.count(x) > 1), None)
    if dup is not None:
        raise _bad("controllers", f"label {dup!r} is used twice; give each a unique label")
    vary_in = doc.get("vary", [])
    if not isinstance(vary_in, list):
        raise _bad("vary", "must be a list of [[vary]] tables")
    vary = tuple(_variation(i, t, spec) for i, t in enumerate(vary_in))
    names = [v.name for v in vary]
    dup = next((x for x in names if names.count(x) > 1), None)
    if dup is not None:
        raise _bad("vary", f"{dup} is varied twice")
    from dataclasses import replace

    spec = replace(spec, controllers=entries, vary=vary)
    if spec.n_points > MAX_POINTS:
        raise _bad("sweep", f"{spec.n_points} points (grid cells x samples); at most "
                            f"{MAX_POINTS} are allowed")
    _check_nominal(spec, names)
    if spec.random == () and spec.samples > 1 and spec.noise_std == 0.0 and \
            "noise_std" not in names:
        raise _bad("sweep.samples", f"{spec.samples} samples of a sweep with nothing random "
                                    f"would repeat identical runs: set samples = 1 or vary "
                                    f"something at random")
    return spec


def _check_nominal(spec: SweepSpec, varied: list[str]) -> None:
    """What every point shares is checked before a run: the delay against the run length,
    the reference against the nominal plant's stroke (a point's own values are checked when it
    runs, an invalid one becomes an ``invalid`` row)."""
    from ..registry import build_plant
    from ..sim.closed_loop import check_delay, plant_limits
    from ..sim.references import check_reference, check_reference_samples, sample_reference

    if "delay" not in varied:
        try:
            check_delay(spec.delay, duration=spec.duration)
        except ParameterError as exc:
            raise _bad("sweep.delay", str(exc)) from None
    ref = parse_reference(spec.reference)
    amp = next((v for v in spec.vary if v.name == "amplitude"), None)
    where = f"vary[{spec.vary.index(amp)}]" if amp is not None else "reference.spec"
    try:
        if amp is None:
            check_reference(ref, ts=spec.ts, duration=spec.duration)
        if any(n in _STROKE_NAMES for n in varied):
            return  # the stroke or the resolution varies: each point is checked alone
        params = spec.nominal
        plant = build_plant(spec.plant, params, spec.start * params.cylinder.stroke,
                            substep=spec.substep)
        t = time_grid(spec.duration, spec.ts)
        stroke, resolution = plant_limits(plant)
    except (InputError, ParameterError) as exc:
        raise _bad("reference.spec", str(exc)) from None
    refs: list[tuple[str, str, Any]]  # (key, what is shown, reference)
    if amp is None:
        refs = [("reference.spec", "", ref)]
    else:  # the grid's values, or the draws nearest each finite bound
        assert isinstance(ref, Step)
        scale = spec.nominal_value("amplitude") if amp.relative else 1.0
        lo, hi = amp.arg("low", -math.inf), amp.arg("high", math.inf)
        if amp.is_grid:
            refs = [(f"{where}.grid", f"amplitude {a!r}: ", Step(scale * a, ref.time))
                    for a in amp.values]
        else:
            refs = [(f"{where}.{k}", f"draws near {k} = {b!r}: ",
                     Step(scale * math.nextafter(b, o), ref.time))
                    for k, b, o in (("low", lo, hi), ("high", hi, lo)) if math.isfinite(b)]
    for key, shown, r in refs:
        try:
            if amp is not None:
                check_reference(r, ts=spec.ts, duration=spec.duration)
            check_reference_samples(plant.y0 + sample_reference(r, t), t, start=plant.y0,
                                    stroke=stroke, resolution=resolution)
        except (InputError, ParameterError) as exc:
            raise _bad(key, shown + str(exc)) from None


# ---- the far tails (drawn in logarithms by sampling._tail_in_logs) ----------------------

#: Below this tail probability the interval's Φ values are drawn in logarithms: Φ(-37.5)
#: is already subnormal and Φ(-38.5) is 0, so a bound 40 standard deviations out put
#: every draw on the far bound.
_LOG_TAIL = 1e-300


def _standard_bounds(var: Variation) -> tuple[float, float]:
    """The bounds of a normal or log-normal variation in standard units (a, b)."""
    lo, hi = var.arg("low", -math.inf), var.arg("high", math.inf)
    if var.distribution == "normal":
        mean, std = var.arg("mean"), var.arg("std")
        return (lo - mean) / std, (hi - mean) / std
    med, sig = var.arg("median"), var.arg("sigma")
    a = math.log(lo / med) / sig if lo > 0.0 else -math.inf
    b = math.log(hi / med) / sig if math.isfinite(hi) else math.inf
    return a, b


def in_log_tail(var: Variation) -> bool:
    """Whether a variation's draws are made in logarithms (``sampling._tail_in_logs``): a normal
    or log-normal truncated to an interval so far in a tail that its Φ underflows."""
    if var.distribution not in ("normal", "log-normal"):
        return False
    a, b = _standard_bounds(var)
    return float(ndtr(-a) if a > 0.0 else ndtr(b)) < _LOG_TAIL
