"""The browser page of ``fuzzyservo app`` (Panel widgets, Bokeh plots; docs/app.md).

One :class:`ServoPage` per browser tab. Every input change makes a new
:class:`~fuzzyservo.app.settings.PageSettings`, submitted to a
:class:`~fuzzyservo.app.latest.Latest` runner: the newest is run (through ``fuzzyservo
simulate``'s own parser and code) and drawn; requests made stale by a newer one are dropped.
Panel is imported here only: ``import fuzzyservo`` and the other commands never load it.
"""

from __future__ import annotations

import contextlib
import hashlib
import html
import io
import math
import os
import shlex
import tempfile
import threading
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import panel as pn
from bokeh.layouts import gridplot
from bokeh.models import ColumnDataSource, Range1d
from bokeh.models.annotations import Legend, LegendItem
from bokeh.plotting import figure

from ..analysis.step_metrics import METRIC_UNITS as UNITS
from ..errors import FuzzyServoError, InputError, UsageError, error_chain
from ..formats.io import MAX_BYTES
from ..paper.published import SET_NAMES, named_set
from ..registry import (
    controller_colour,
    controller_kind,
    controller_names,
    controller_options,
    plant_names,
)
from ..sim import Step, parse_reference
from .latest import Latest
from .settings import (
    PAGE_RUN,
    PHYSICAL,
    WARMED,
    PageRun,
    PageSettings,
    default_gains,
    error_line,
    run_page,
    shift,
)

__all__ = ["MAX_PINS", "ServoPage", "gain_range", "pin_colour"]

#: Runs that can be pinned for comparison.
MAX_PINS = 4

def pin_colour(controller: str) -> str:
    """The colour of a pinned run of ``controller``: the registry's colour of the kind
    (:func:`~fuzzyservo.registry.controller_colour`: the study's colour of that controller,
    or for a kind registered without one a colour by its position in the registry)."""
    return controller_colour(controller)


#: Line styles of the second, third and fourth pinned run of one controller.
_DASHES = ("solid", "dashed", "dotted", "dashdot")

#: Reference shapes and the spec each starts from (offsets from the start position, m, s).
REFERENCE_EXAMPLES: dict[str, str] = {
    "step": "step:0.1",
    "multistep": "multistep:0=0.05,2=0.1,3.5=0.02",
    "ramp": "ramp:0.05:0.5:0.15",
    "sine": "sine:0.05:0.5",
    "trapezoid": "trapezoid:0.1:0.1:0.5",
}

_LIVE_COLOUR = "#000000"


#: Largest fuzzy-system file the page takes [bytes]: the file readers' limit, the command's.
MAX_UPLOAD_BYTES = MAX_BYTES


def upload_name(filename: str | None, size: int) -> str:
    """The name under which an uploaded fuzzy-system file is kept: the browser's name of it,
    a plain file name with a .fis, .fcl or .fll extension, at most
    :data:`MAX_UPLOAD_BYTES` long (the command's readers' limit).

    Raises
    ------
    InputError
        A name that is not a plain file name, or a file too large.
    ParameterError
        Another extension (the readers' own line).
    """
    from ..formats import format_of

    name = os.path.basename(filename or "")
    if name in ("", ".", "..") or any(ord(c) < 32 or c == "\x7f" for c in name):
        raise InputError(f"uploaded file {filename!r}: not a file name")
    format_of(name)  # the reader's line for another extension
    if size > MAX_UPLOAD_BYTES:
        raise InputError(f"uploaded file {name}: {size} bytes is larger than the "
                         f"{MAX_UPLOAD_BYTES}-byte limit")
    return name


def gain_range(controller: str, name: str, step: float) -> tuple[float, float, bool]:
    """The slider of gain ``name`` of ``controller``: (low, high, logarithmic), from the
    registry (its ``slider`` range, else the tuner's box; a per-step gain's box scaled by
    1/|step|, ``step`` in metres)."""
    g = controller_kind(controller).gain(name)
    box = g.slider if g.slider is not None else g.search
    assert box is not None, f"gain {name} has neither a slider range nor a tuning box"
    lo, hi = box
    if g.per_step and g.slider is None:
        scale = 1.0 / abs(step) if step != 0.0 and math.isfinite(step) else 10.0
        lo, hi = lo * scale, hi * scale
    return float(lo), float(hi), bool(g.log and lo > 0.0)


def _prompt(widget: Any) -> Any:
    """``widget`` with Panel's merge delay of browser changes set to 0.

    Panel holds every change that comes from the browser for 50 ms (``Syncable._debounce``)
    to merge a burst; that was half the page's redraw time. The page's own runner
    (:class:`~fuzzyservo.app.latest.Latest`) already drops requests made stale by newer
    ones, so the page's inputs are taken at once (docs/app.md, "Responsive")."""
    widget._debounce = 0
    return widget


def _whole(value: int | None, flag: str) -> int:
    """A whole-number input of the tuner, refused as ``fuzzyservo tune`` refuses it when
    empty."""
    if value is None:
        raise UsageError(f"fuzzyservo tune: error: argument {flag}: invalid int value: "
                         f"'None'")
    return int(value)


def _round3(v: float) -> float:
    """A slider position as a number a person would type: 3 significant digits."""
    return float(f"{v:.3g}")


def _step_of(spec: str) -> Step | None:
    """The step a reference spec names (the CLI's parser), None for another shape or a spec
    that does not parse (the run reports that)."""
    try:
        ref = parse_reference(spec)
    except FuzzyServoError:
        return None
    return ref if isinstance(ref, Step) else None


@dataclass(frozen=True, slots=True)
class _Pin:
    label: str
    colour: str
    dash: str
    run: PageRun


class _GainRow:
    """A gain's slider and number box, linked: the slider moves on a log scale for gains that
    span decades; the number box holds the value that is run."""

    def __init__(self, controller: str, name: str, value: float, step: float,
                 on_value: Callable[[str, float], None]) -> None:
        spec = controller_kind(controller).gain(name)
        self.name = name
        self.lo, self.hi, self.log = gain_range(controller, name, step)
        label = f"{name} [{spec.unit}]"
        self.on_value = on_value
        self.busy = False
        if self.log:
            self.slider = pn.widgets.FloatSlider(
                name=f"{label}, log scale", start=math.log10(self.lo), end=math.log10(self.hi),
                step=0.005, value=self._pos(value), show_value=False,
                css_classes=[f"fs-slider-{name}"], sizing_mode="stretch_width")
        else:
            self.slider = pn.widgets.FloatSlider(
                name=label, start=self.lo, end=self.hi, step=(self.hi - self.lo) / 200,
                value=self._pos(value), show_value=False, css_classes=[f"fs-slider-{name}"],
                sizing_mode="stretch_width")
        self.box = pn.widgets.FloatInput(value=value, width=125,
                                         css_classes=[f"fs-gain-{name}"],
                                         description=spec.description, format="0[.]000000")
        _prompt(self.slider)
        _prompt(self.box)
        self.slider.param.watch(self._slid, "value")
        self.box.param.watch(self._typed, "value")
        self.view = pn.Row(self.slider, self.box, sizing_mode="stretch_width")

    def _pos(self, value: float) -> float:
        if self.log:
            v = min(max(value, self.lo), self.hi) if math.isfinite(value) else self.hi
            return math.log10(v) if v > 0 else math.log10(self.lo)
        return min(max(value, self.lo), self.hi)

    def _slid(self, event: Any) -> None:
        if self.busy:
            return
        value = _round3(10.0 ** event.new) if self.log else _round3(event.new)
        self.busy = True
        try:
            self.box.value = value
        finally:
            self.busy = False
        self.on_value(self.name, value)

    def _typed(self, event: Any) -> None:
        if self.busy:
            return
        value = event.new
        if value is None:
            return
        self.busy = True
        try:
            if isinstance(value, int | float) and not math.isnan(value):
                self.slider.value = self._pos(float(value))
        finally:
            self.busy = False
        self.on_value(self.name, float(value))

    def set(self, value: float) -> None:
        """Show ``value`` (e.g. the tuner's) without reporting it back."""
        self.busy = True
        try:
            self.box.value = value
            self.slider.value = self._pos(value)
        finally:
            self.busy = False


class ServoPage:
    """The page of one browser tab.

    Parameters
    ----------
    param_set : str
        The parameter set the page starts with.
    workdir : Path
        Folder for the fuzzy-system files a user uploads (the copied command names them).
    """

    def __init__(self, *, param_set: str = "paper", workdir: Path) -> None:
        self.workdir = workdir
        self.doc: Any = pn.state.curdoc
        self.latest: Latest[PageSettings, PageRun] = Latest(run_page, self._deliver)
        self.current: PageRun | None = None
        self.pins: list[_Pin] = []
        self.tuned: Any = None  # TunedGains of the last tuning, while the gains are its
        self.tuning: tuple[str, str] = ("", "")  # controller and plant being tuned
        self.tune_stop = threading.Event()
        self.systems: dict[str, str] = {}
        self._figures: dict[tuple[str, str], Any] = {}
        self._quiet = False
        self.settings = PageSettings(param_set=param_set,
                                     gains=default_gains(PAGE_RUN.controller, PAGE_RUN.plant))
        self._build_inputs()
        self._build_outputs()
        self._build_actions()
        self.view = self._layout()
        for w in self.view.select(pn.widgets.Widget):
            _prompt(w)
        self._rebuild_gains()
        if not WARMED.is_set():
            self.w_status.object = (
                "warming up: compiling the simulation kernels (once per install, then they "
                "load in a fraction of a second); the first run follows in a few seconds")
        self.submit()

    # ------------------------------------------------------------------ inputs

    def _build_inputs(self) -> None:
        names = controller_names()
        self.w_controller = pn.widgets.Select(
            name="controller", value=self.settings.controller,
            options={f"{n}: {controller_kind(n).title}": n for n in names},
            css_classes=["fs-controller"])
        self.w_plant = pn.widgets.Select(name="plant", options=list(plant_names()),
                                         value=self.settings.plant, css_classes=["fs-plant"],
                                         width=160)
        self.w_set = pn.widgets.Select(name="parameter set", options=list(SET_NAMES),
                                       value=self.settings.param_set, css_classes=["fs-set"],
                                       width=160)
        self.gain_rows: dict[str, _GainRow] = {}
        self.gain_column = pn.Column(sizing_mode="stretch_width")
        self.phys: dict[str, tuple[Any, Any]] = {}
        rows = []
        for ph in PHYSICAL:
            slider = pn.widgets.FloatSlider(name=f"{ph.label} [{ph.unit}]", start=0.0,
                                            end=1.0, step=0.0025, show_value=False,
                                            sizing_mode="stretch_width",
                                            css_classes=[f"fs-slider-{ph.key}"])
            box = pn.widgets.FloatInput(width=125, css_classes=[f"fs-phys-{ph.key}"])
            self.phys[ph.key] = (slider, box)
            slider.param.watch(partial(self._phys_slid, ph.key), "value")
            box.param.watch(partial(self._phys_typed, ph.key), "value")
            rows.append(pn.Row(slider, box, sizing_mode="stretch_width"))
        self.phys_column = pn.Column(*rows, sizing_mode="stretch_width")
        self._reset_physical()
        self.w_shape = pn.widgets.Select(name="reference", options=list(REFERENCE_EXAMPLES),
                                         value="step", css_classes=["fs-shape"])
        self.w_step = pn.widgets.FloatSlider(name="step size [mm]", start=-300.0, end=300.0,
                                             step=1.0, value=100.0,
                                             sizing_mode="stretch_width",
                                             css_classes=["fs-step"])
        self.w_spec = pn.widgets.TextInput(name="reference spec (offset from the start) [m, s]",
                                           value=self.settings.reference,
                                           css_classes=["fs-spec"])
        self.w_load = pn.widgets.TextInput(
            name="load force [N, s] (> 0 opposes extension)", value=self.settings.load_force,
            placeholder="none; step:F:T, pwl:T0:F0,T1:F1,... or FILE.csv",
            css_classes=["fs-load"])
        self.w_duration = pn.widgets.FloatInput(name="duration [s]", value=5.0, width=110,
                                                css_classes=["fs-duration"])
        self.w_ts = pn.widgets.FloatInput(name="sample time [ms]", value=1.0, width=110,
                                          css_classes=["fs-ts"])
        self.w_start = pn.widgets.FloatInput(name="start [x stroke]", value=0.5,
                                             width=120, css_classes=["fs-start"])
        self.w_seed = pn.widgets.IntInput(name="noise seed", value=0, width=110,
                                          css_classes=["fs-seed"])
        self.w_options: dict[str, Any] = {}
        for o in controller_options():  # as the registry declares them
            if o.choices:
                w: Any = pn.widgets.Select(name=o.label, options=["(default)", *o.choices],
                                           value="(default)", width=150)
            else:
                unit = f" [{o.unit}]" if o.unit else ""
                w = pn.widgets.FloatInput(name=f"{o.label}{unit}", value=None, width=150,
                                          placeholder=f"(default {o.default_text()})")
            w.param.watch(self._changed, "value")
            self.w_options[o.name] = w
        for w in (self.w_duration, self.w_ts, self.w_start, self.w_seed):
            w.param.watch(self._changed, "value")
        self.w_controller.param.watch(self._controller_changed, "value")
        self.w_plant.param.watch(self._plant_changed, "value")
        self.w_set.param.watch(self._set_changed, "value")
        self.w_shape.param.watch(self._shape_changed, "value")
        self.w_step.param.watch(self._step_moved, "value")
        self.w_spec.param.watch(self._changed, "value")
        self.w_load.param.watch(self._changed, "value")

    def _reset_physical(self) -> None:
        """Show the parameter set's values (and no delay, no noise)."""
        params = named_set(self.w_set.value)
        self._quiet = True
        try:
            for ph in PHYSICAL:
                slider, box = self.phys[ph.key]
                if "." not in ph.key:  # a run option (delay, noise): none
                    si = 0.0
                else:
                    group, fld = ph.key.split(".")
                    si = float(getattr(getattr(params, group), fld))
                shown = ph.from_si(si)
                lo, hi = (ph.low * shown, ph.high * shown) if ph.relative else (ph.low,
                                                                                 ph.high)
                slider.param.update(start=lo, end=hi, step=(hi - lo) / 400)
                box.value = shown
                slider.value = min(max(shown, lo), hi)
        finally:
            self._quiet = False
        self._phys_si: dict[str, float] = {}

    def _phys_slid(self, key: str, event: Any) -> None:
        if self._quiet:
            return
        ph = next(p for p in PHYSICAL if p.key == key)
        self._quiet = True
        try:
            self.phys[key][1].value = _round3(event.new)
        finally:
            self._quiet = False
        self._phys_si[key] = ph.to_si(_round3(event.new))
        self.submit()

    def _phys_typed(self, key: str, event: Any) -> None:
        if self._quiet or event.new is None:
            return
        ph = next(p for p in PHYSICAL if p.key == key)
        self._quiet = True
        try:
            slider = self.phys[key][0]
            if math.isfinite(event.new):
                slider.value = min(max(event.new, slider.start), slider.end)
        finally:
            self._quiet = False
        self._phys_si[key] = ph.to_si(float(event.new))
        self.submit()

    def _rebuild_gains(self) -> None:
        ref = _step_of(str(self.w_spec.value))
        step = ref.amplitude if ref is not None else 0.1
        self.gain_rows = {}
        for name, value in self.settings.gains:
            self.gain_rows[name] = _GainRow(self.settings.controller, name, value, step,
                                            self._gain_changed)
        self.gain_column.objects = [r.view for r in self.gain_rows.values()]
        kind = controller_kind(self.settings.controller)
        for key, w in self.w_options.items():
            w.visible = key in kind.option_names

    def _gain_changed(self, name: str, value: float) -> None:
        self.tuned = None
        self.submit()

    def _controller_changed(self, event: Any) -> None:
        self.tuned = None
        self.settings = self.settings.replace(
            controller=event.new, gains=default_gains(event.new, self.w_plant.value))
        self._quiet = True
        try:
            for w in self.w_options.values():
                w.value = "(default)" if isinstance(w, pn.widgets.Select) else None
        finally:
            self._quiet = False
        self._rebuild_gains()
        self.submit()
        if self.tabs.active == 2:
            self._refresh_systems_tab()

    def _plant_changed(self, event: Any) -> None:
        """A new plant starts from that plant's shipped tuned gains."""
        self.tuned = None
        self.settings = self.settings.replace(
            gains=default_gains(self.settings.controller, event.new))
        self._rebuild_gains()
        self.submit()

    def _set_changed(self, event: Any) -> None:
        self._reset_physical()
        self.submit()

    def _shape_changed(self, event: Any) -> None:
        self._quiet = True
        try:
            if event.new == "step":
                self.w_spec.value = f"step:{_round3(float(self.w_step.value or 0.0) / 1e3)!r}"
            else:
                self.w_spec.value = REFERENCE_EXAMPLES[event.new]
        finally:
            self._quiet = False
        self.w_step.visible = event.new == "step"
        self.submit()

    def _step_moved(self, event: Any) -> None:
        if self._quiet:
            return
        self._quiet = True
        try:
            self.w_spec.value = f"step:{_round3(event.new / 1000.0)!r}"
        finally:
            self._quiet = False
        self.submit()

    def _changed(self, event: Any) -> None:
        if not self._quiet:
            self.submit()

    # ------------------------------------------------------------------ settings and runs

    def read_settings(self) -> PageSettings:
        """The settings the inputs show (SI)."""
        gains = tuple((n, float(r.box.value) if r.box.value is not None else math.nan)
                      for n, r in self.gain_rows.items())
        params = named_set(self.w_set.value)
        overrides = []
        delay = noise = 0.0
        for ph in PHYSICAL:
            si = self._phys_si.get(ph.key)
            if ph.key == "delay":
                delay = si or 0.0
            elif ph.key == "noise_std":
                noise = si or 0.0
            elif si is not None:
                group, fld = ph.key.split(".")
                if si != float(getattr(getattr(params, group), fld)):
                    overrides.append((ph.key, si))
        options: list[tuple[str, Any]] = []
        for key, w in self.w_options.items():
            if not w.visible:
                continue
            if isinstance(w, pn.widgets.Select):
                if w.value != "(default)":
                    options.append((key, str(w.value)))
            elif w.value is not None:
                options.append((key, float(w.value)))
        kind = controller_kind(self.w_controller.value)
        systems = tuple((role, path) for role, path in sorted(self.systems.items())
                        if role in kind.systems)

        def num(w: Any, exponent: int = 0) -> float:
            return math.nan if w.value is None else shift(float(w.value), exponent)

        return PageSettings(
            controller=self.w_controller.value, gains=gains, plant=self.w_plant.value,
            param_set=self.w_set.value, overrides=tuple(overrides), delay=delay,
            noise_std=noise, seed=int(self.w_seed.value or 0),
            reference=str(self.w_spec.value or "").strip(),
            load_force=str(self.w_load.value or "").strip(), duration=num(self.w_duration),
            ts=num(self.w_ts, -3), start=num(self.w_start), options=tuple(options),
            systems=systems,
            no_rule_value=(None if self.w_no_rule.value is None or not systems
                           else float(self.w_no_rule.value)))

    def submit(self) -> None:
        """Run the settings the inputs show (the newest request wins)."""
        self.settings = self.read_settings()
        self.w_command.value = self.settings.command()
        self.latest.submit(self.settings)

    def _deliver(self, seq: int, result: PageRun | BaseException) -> None:
        try:
            self.doc.add_next_tick_callback(partial(self._apply, seq, result))
        except Exception:  # the tab was closed
            pass

    def _apply(self, seq: int, result: PageRun | BaseException) -> None:
        if seq != self.latest.newest:
            return  # a newer request is on its way: this one is stale
        stats = self.latest.stats()
        if isinstance(result, BaseException):
            self.w_error.object = html.escape(error_line(result))
            self.w_error.visible = True
            self.w_status.object = (f"request {seq}: not run &middot; {stats.dropped} stale "
                                    f"requests dropped")
            return
        self.w_error.visible = False
        self.current = result
        self._draw()
        notes = "".join(f"<br>note: {html.escape(n)}" for n in result.notes)
        self.w_status.object = (f"request {seq}: run in {1e3 * result.seconds:.1f} ms "
                                f"&middot; {stats.ran} runs, {stats.dropped} stale requests "
                                f"dropped{notes}")

    # ------------------------------------------------------------------ outputs

    def _build_outputs(self) -> None:
        tools = "pan,box_zoom,wheel_zoom,reset,save"
        self.src_live = ColumnDataSource(data=self._columns(None), name="fs-live")
        self.src_pins = [ColumnDataSource(data=self._columns(None), name=f"fs-pin-{i}")
                         for i in range(MAX_PINS)]
        fy = figure(height=300, sizing_mode="stretch_width", tools=tools,
                    y_axis_label="position [mm]", title="position and reference")
        fu = figure(height=190, sizing_mode="stretch_width", tools=tools, x_range=fy.x_range,
                    y_axis_label="command u [% of rated]")
        fa = figure(height=160, sizing_mode="stretch_width", tools=tools, x_range=fy.x_range,
                    y_axis_label="α [-]", x_axis_label="time [s]",
                    y_range=Range1d(start=0.0, end=1.05))
        legend_items: list[Any] = []
        self.pin_renderers: list[list[Any]] = []
        for i, src in enumerate(self.src_pins):
            rs: list[Any] = [fy.line("t", "y_mm", source=src, line_width=1.6),
                  fy.line("t", "r_mm", source=src, line_width=1.0, line_dash="dashed",
                          line_alpha=0.7),
                  fu.step("t", "u_pct", source=src, mode="after", line_width=1.2),
                  fa.step("t", "alpha", source=src, mode="after", line_width=1.2)]
            for r in rs:
                r.visible = False
            self.pin_renderers.append(rs)
            legend_items.append(LegendItem(label=f"pin {i + 1}", renderers=[rs[0]],
                                           visible=False))
        ref: Any = fy.line("t", "r_mm", source=self.src_live, color="#555555", line_width=1.0,
                           line_dash=[4, 3])
        live: Any = fy.line("t", "y_mm", source=self.src_live, color=_LIVE_COLOUR, line_width=2.0)
        fu.step("t", "u_pct", source=self.src_live, mode="after", color=_LIVE_COLOUR,
                line_width=1.4)
        fa.step("t", "alpha", source=self.src_live, mode="after", color=_LIVE_COLOUR,
                line_width=1.4)
        self.legend = Legend(items=[LegendItem(label="this run", renderers=[live]),
                                    LegendItem(label="reference", renderers=[ref]),
                                    *legend_items], orientation="horizontal",
                             click_policy="hide")
        fy.add_layout(self.legend, "above")
        self.fig_alpha = fa
        self.plots = pn.pane.Bokeh(gridplot([[fy], [fu], [fa]], toolbar_location="right",
                                            sizing_mode="stretch_width"),
                                   sizing_mode="stretch_width", min_width=420)
        self.w_metrics = pn.pane.HTML("", css_classes=["fs-metrics"], width=540)
        # HTML, not Markdown: a message's "noise_std" or "*" must show as written
        self.w_error = pn.pane.HTML("", visible=False, css_classes=["fs-error"],
                                    sizing_mode="stretch_width",
                                    styles={"color": "#842029", "background": "#f8d7da",
                                            "border": "1px solid #f5c2c7",
                                            "border-radius": "4px", "padding": "0 10px",
                                            "font-family": "monospace"})
        self.w_status = pn.pane.HTML("", css_classes=["fs-status"],
                                     styles={"color": "#555", "font-size": "12px"})
        self.w_command = pn.widgets.TextAreaInput(name="the command that makes this run",
                                                  value="", height=90,
                                                  sizing_mode="stretch_width",
                                                  css_classes=["fs-command"])
        # what is copied is the command of the settings: an edit in the box is undone
        self.w_command.param.watch(self._command_edited, "value")

    def _command_edited(self, event: Any) -> None:
        if event.new != self.settings.command():
            self.w_command.value = self.settings.command()

    @staticmethod
    def _columns(run: PageRun | None) -> dict[str, Any]:
        if run is None:
            e = np.empty(0)
            return {"t": e, "r_mm": e, "y_mm": e, "u_pct": e, "alpha": e}
        return {"t": run.t, "r_mm": 1e3 * run.r, "y_mm": 1e3 * run.y, "u_pct": 100.0 * run.u,
                "alpha": run.alpha}

    def _draw(self) -> None:
        run = self.current
        assert run is not None
        self.src_live.data = self._columns(run)
        has_alpha = bool(np.isfinite(run.alpha).any()) or any(
            bool(np.isfinite(p.run.alpha).any()) for p in self.pins)
        self.fig_alpha.visible = has_alpha
        self._metrics_table()

    def _metrics_table(self) -> None:
        runs: list[tuple[str, str, PageRun]] = []
        if self.current is not None:
            runs.append(("this run", _LIVE_COLOUR, self.current))
        runs += [(f"pin {i + 1}", p.colour, p.run) for i, p in enumerate(self.pins)]
        head = "".join(f'<th style="color:{c};text-align:right">{html.escape(n)}</th>'
                       for n, c, _ in runs)
        body = []
        names = list(runs[0][2].metrics) if runs else []
        for name in names:
            cells = "".join(f'<td style="text-align:right;padding-left:10px" '
                            f'data-metric="{name}">'
                            f'{r.metrics[name]:.6g}</td>' for _, _, r in runs)
            body.append(f"<tr><td>{name}</td>{cells}<td>{html.escape(UNITS[name])}</td></tr>")
        self.w_metrics.object = (
            '<table class="fs-metrics-table" style="font-size:12px;border-collapse:collapse">'
            f"<tr><th>step metric</th>{head}<th>unit</th></tr>{''.join(body)}</table>")

    # ------------------------------------------------------------------ pins

    def pin(self, event: Any = None) -> None:
        """Pin the current run (up to :data:`MAX_PINS`)."""
        if self.current is None:
            return
        if len(self.pins) >= MAX_PINS:
            self.w_error.object = (f"fuzzyservo: error: {MAX_PINS} runs are pinned already; "
                                   f"unpin one first")
            self.w_error.visible = True
            return
        s = self.current.settings
        colour = pin_colour(s.controller)
        used = {p.dash for p in self.pins if p.run.settings.controller == s.controller}
        dash = next((d for d in _DASHES if d not in used), _DASHES[0])
        gains = ", ".join(f"{k}={v:.4g}" for k, v in s.gains)
        label = f"{s.controller} ({gains}), {s.plant}"
        self.pins.append(_Pin(label, colour, dash, self.current))
        self._draw_pins()

    def unpin(self, index: int, event: Any = None) -> None:
        """Remove pinned run ``index``."""
        if 0 <= index < len(self.pins):
            del self.pins[index]
            self._draw_pins()

    def clear_pins(self, event: Any = None) -> None:
        """Remove every pinned run."""
        self.pins = []
        self._draw_pins()

    def _draw_pins(self) -> None:
        for i, (src, rs) in enumerate(zip(self.src_pins, self.pin_renderers, strict=True)):
            pin = self.pins[i] if i < len(self.pins) else None
            src.data = self._columns(pin.run if pin else None)
            for r in rs:
                r.visible = pin is not None
                if pin is not None:
                    r.glyph.line_color = pin.colour
                    if r is not rs[1]:
                        r.glyph.line_dash = pin.dash
            item: Any = self.legend.items[2 + i]
            item.label = {"value": (f"pin {i + 1}: {pin.run.settings.controller}" if pin
                                    else f"pin {i + 1}")}
            item.visible = pin is not None
        rows = []
        for i, p in enumerate(self.pins):
            b = pn.widgets.Button(name="unpin", button_type="light", width=70,
                                  css_classes=[f"fs-unpin-{i}"])
            b.on_click(partial(self.unpin, i))
            rows.append(pn.Row(pn.pane.HTML(
                f'<span style="color:{p.colour};font-weight:bold">pin {i + 1} '
                f'({p.dash})</span>: {html.escape(p.label)}', sizing_mode="stretch_width"), b))
        self.pin_list.objects = rows
        if self.current is not None:
            self._draw()

    # ------------------------------------------------------------------ actions

    def _build_actions(self) -> None:
        self.b_pin = pn.widgets.Button(name="pin this run", button_type="primary",
                                       css_classes=["fs-pin"])
        self.b_pin.on_click(self.pin)
        self.b_clear = pn.widgets.Button(name="clear pins", css_classes=["fs-clear"])
        self.b_clear.on_click(self.clear_pins)
        self.pin_list = pn.Column(sizing_mode="stretch_width")
        self.b_copy = pn.widgets.Button(name="copy the command", css_classes=["fs-copy"])
        self.b_copy.js_on_click(args={"box": self.w_command},
                                code="navigator.clipboard.writeText(box.value)")
        self.d_gains = pn.widgets.FileDownload(callback=self._gains_file, filename="gains.toml",
                                               label="gains (.toml for simulate --gains)",
                                               css_classes=["fs-dl-gains"])
        self.d_csv = pn.widgets.FileDownload(callback=self._csv_file, filename="run.csv",
                                             label="run (.csv)", css_classes=["fs-dl-csv"])
        self.d_c = pn.widgets.FileDownload(callback=self._c_file, filename="controller-c.zip",
                                           label="controller as C99 (.zip)",
                                           css_classes=["fs-dl-c"])
        self.d_fmu = pn.widgets.FileDownload(callback=self._fmu_file, filename="controller.fmu",
                                             label="controller as FMU (.fmu)",
                                             css_classes=["fs-dl-fmu"])
        self.d_st = pn.widgets.FileDownload(callback=self._st_file, filename="controller-st.zip",
                                            label="controller as IEC 61131-3 Structured Text "
                                                  "(.zip)",
                                            css_classes=["fs-dl-st"])
        # tuner
        self.w_objective = pn.widgets.Select(name="objective", options=["itae", "iae", "ise"],
                                             value="itae", width=100)
        self.w_maxiter = pn.widgets.IntInput(name="max generations per stage", value=500,
                                             width=170, css_classes=["fs-maxiter"])
        self.w_restarts = pn.widgets.IntInput(name="searches per stage", value=3, width=140,
                                              css_classes=["fs-restarts"])
        self.w_popsize = pn.widgets.IntInput(name="population x", value=10, width=110)
        self.w_max_os = pn.widgets.FloatInput(name="max overshoot [%] (empty: tune's 10)",
                                              value=None, width=200)
        self.b_tune = pn.widgets.Button(name="tune", button_type="primary",
                                        css_classes=["fs-tune"])
        self.b_tune.on_click(self.start_tuning)
        self.b_stop = pn.widgets.Button(name="stop", disabled=True, css_classes=["fs-stop"])
        self.b_stop.on_click(lambda e: self.tune_stop.set())
        self.w_tune_progress = pn.indicators.Progress(value=0, max=1000, width=420,
                                                      css_classes=["fs-tune-progress"])
        self.w_tune_status = pn.pane.HTML("", css_classes=["fs-tune-status"])
        self.w_tune_command = pn.pane.HTML("", css_classes=["fs-tune-command"],
                                           styles={"font-family": "monospace",
                                                   "font-size": "12px"})
        # fuzzy systems
        self.w_du_file = pn.widgets.FileInput(accept=".fis,.fcl,.fll",
                                              css_classes=["fs-du-file"])
        self.w_alpha_file = pn.widgets.FileInput(accept=".fis,.fcl,.fll",
                                                 css_classes=["fs-alpha-file"])
        self.w_du_file.param.watch(partial(self._system_file, "du"), "value")
        self.w_alpha_file.param.watch(partial(self._system_file, "alpha"), "value")
        self.b_paper_systems = pn.widgets.Button(name="back to the paper's systems")
        self.b_paper_systems.on_click(self._paper_systems)
        self.w_no_rule = pn.widgets.FloatInput(name="value where no rule fires (files only)",
                                               value=None, width=250)
        self.w_no_rule.param.watch(self._changed, "value")
        self.systems_view = pn.Column(sizing_mode="stretch_width")

    def _shown(self) -> PageSettings:
        """The settings of the run the page shows (after an error, the last good one's: the
        downloads are of what is drawn)."""
        return self.current.settings if self.current is not None else self.settings

    def _gains_file(self) -> io.BytesIO:
        from ..files import write_gains_toml

        s = self._shown()
        t = self.tuned
        if (t is not None and t.controller == s.controller and t.setup.plant == s.plant
                and dict(t.gains) == s.gain_map()):
            self.d_gains.filename = f"{s.controller}-tuned.toml"
            with tempfile.TemporaryDirectory() as d:
                path = write_gains_toml(Path(d) / "gains.toml", t)
                return io.BytesIO(path.read_bytes())
        import tomli_w

        doc = {"controller": s.controller, "gains": dict(s.gains)}
        head = (f"# gains of the browser page (fuzzyservo app); the run it showed:\n"
                f"# {s.command()}\n")
        self.d_gains.filename = f"{s.controller}-gains.toml"
        return io.BytesIO((head + tomli_w.dumps(doc)).encode())

    def _csv_file(self) -> io.BytesIO:
        if self.current is None:
            return io.BytesIO(b"")
        buf = io.StringIO()
        self.current.result.to_csv(buf)
        return io.BytesIO(buf.getvalue().encode())

    def _export_args(self, target: str, out: str) -> list[str]:
        """``fuzzyservo export TARGET`` arguments of the shown controller (the run's
        controller part, as :class:`~fuzzyservo.run.RunSpec` writes it)."""
        return ["export", target, *self._shown().run_spec().controller_args(), "--out", out]

    def _export(self, target: str, out: Path, shown: str) -> None:
        """Export the shown controller as ``fuzzyservo export TARGET`` would into ``out``;
        the files record that command with ``--out shown``, the name the download has (so
        that command, run in the folder of the download, writes the same files byte for
        byte)."""
        from ..export.targets import (
            export_c,
            export_controller_fmu,
            export_st,
            generate_c,
            generate_st,
        )
        from ..run import systems_record

        spec = self._shown().run_spec()
        ctl = spec.build_controller()
        command = "fuzzyservo " + shlex.join(self._export_args(target, shown))
        if target == "st":
            st = generate_st(spec.controller, ctl.gains, ts=spec.ts, systems=ctl.systems,
                             options=ctl.options, real="LREAL", name=None,
                             systems_record=systems_record(ctl.systems), command=command)
            export_st(st, out)
            return
        cc = generate_c(spec.controller, ctl.gains, ts=spec.ts, systems=ctl.systems,
                        options=ctl.options, real="double", name=None,
                        systems_record=systems_record(ctl.systems), command=command)
        if target == "c":
            export_c(cc, out)
        else:
            export_controller_fmu(cc, out, command=command)

    def _zipped_export(self, target: str, download: Any) -> io.BytesIO | None:
        """The folder ``fuzzyservo export TARGET`` writes, as ``<controller>-TARGET.zip``
        (the files flat, as the folder holds them); None after showing an error."""
        try:
            with tempfile.TemporaryDirectory() as d:
                shown = f"{self._shown().controller}-{target}"
                out = Path(d) / target
                self._export(target, out, shown)
                buf = io.BytesIO()
                with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
                    for f in sorted(out.iterdir()):
                        z.write(f, f.name)
                buf.seek(0)
                download.filename = f"{shown}.zip"
                return buf
        except Exception as exc:
            self._show_error(exc)
            return None

    def _c_file(self) -> io.BytesIO | None:
        return self._zipped_export("c", self.d_c)

    def _st_file(self) -> io.BytesIO | None:
        return self._zipped_export("st", self.d_st)

    def _fmu_file(self) -> io.BytesIO | None:
        try:
            with tempfile.TemporaryDirectory() as d:
                out = Path(d) / f"{self._shown().controller}.fmu"
                self._export("fmu", out, out.name)
                self.d_fmu.filename = out.name
                return io.BytesIO(out.read_bytes())
        except Exception as exc:
            self._show_error(exc)
            return None

    def _show_error(self, exc: BaseException) -> None:
        self.w_error.object = html.escape(error_line(exc))
        self.w_error.visible = True

    # ------------------------------------------------------------------ tuner

    def tune_argv(self) -> list[str]:
        """``fuzzyservo tune`` arguments that tune the controller on the page's plant."""
        s = self.settings
        if s.options:
            raise InputError(f"the tuner tunes with the controller's default options; set "
                             f"{', '.join(s.option_flags())} back to (default) in "
                             f"'controller options' to tune")
        ref = _step_of(s.reference)
        if ref is None or ref.time != 0.0:
            raise InputError(f"the tuner tunes a step response from t = 0: choose the "
                             f"reference step:A, not {s.reference!r}")
        argv = ["tune", "--controller", s.controller, "--plant", s.plant,
                f"--step={ref.amplitude!r}",
                f"--duration={s.duration!r}", f"--ts={s.ts!r}", f"--start={s.start!r}",
                f"--delay={s.delay!r}", "--objective", str(self.w_objective.value),
                "--maxiter", str(self.w_maxiter.value), "--restarts",
                str(self.w_restarts.value), "--popsize", str(self.w_popsize.value)]
        if self.w_max_os.value is not None:
            argv += [f"--max-overshoot={float(self.w_max_os.value)!r}"]
        spec = s.run_spec()
        return [*argv, *spec.system_args(), *spec.parameter_args()]

    def tuning_setup(self) -> tuple[Any, Any, Any]:
        """What ``fuzzyservo tune`` with :meth:`tune_argv` tunes: its setup, the servo
        parameters and the fuzzy systems, checked with the command's messages."""
        from ..analysis.autotune import TuningSetup
        from ..analysis.tuning import StopRule, TuningConstraints
        from ..run import load_systems, systems_record

        self.tune_argv()  # the same refusals
        spec = self.settings.run_spec()
        params = spec.checked_params()
        systems = load_systems(spec.controller, dict(spec.systems), spec.no_rule_value)
        constraints = TuningConstraints.from_limits(
            max_overshoot=10.0 if self.w_max_os.value is None else float(self.w_max_os.value),
            max_sse_percent=0.2, max_u=None)
        stop = StopRule()
        # the tuner's runs are noise-free, as the command tune_argv shows
        setup = TuningSetup.for_run(
            replace(spec, delay=spec.checked_delay(params), noise_std=0.0, seed=0),
            systems=systems_record(systems),
            objective=str(self.w_objective.value), constraints=constraints, seed=0,
            popsize=_whole(self.w_popsize.value, "--popsize"),
            maxiter=_whole(self.w_maxiter.value, "--maxiter"),
            patience=stop.patience, rtol=stop.rtol, spread=stop.spread,
            restarts=_whole(self.w_restarts.value, "--restarts"), polish=True)
        return setup, params, systems

    def start_tuning(self, event: Any = None) -> None:
        """Run the tuner in a thread; its progress is shown, its result loaded."""
        try:
            argv = self.tune_argv()
            job = self.tuning_setup()
        except Exception as exc:
            self._show_error(exc)
            return
        self.w_tune_command.object = html.escape(
            "fuzzyservo " + shlex.join([*argv, "--out", "gains.toml"]))
        self.tune_stop.clear()
        self.tuning = (self.settings.controller, self.settings.plant)
        self.b_tune.disabled = True
        self.b_stop.disabled = False
        self.w_tune_progress.value = 0
        threading.Thread(target=self._tune, args=job, daemon=True,
                         name="fuzzyservo-tune").start()

    def _tune(self, setup: Any, params: Any, systems: Any) -> None:
        from ..analysis.autotune import tune_controller

        started = time.monotonic()
        last = [0.0]

        class Stopped(Exception):
            pass

        def progress(p: Any) -> None:
            if self.tune_stop.is_set():
                raise Stopped
            now = time.monotonic()
            if now - last[0] < 0.2 and p.generation != 0:
                return
            last[0] = now
            label = p.stage + (f" {p.restart + 1}/{p.restarts}" if p.restarts > 1 else "")
            runs = p.n_evaluations
            rate = runs / max(now - started, 1e-9)
            text = (f"stage {label}: generation {p.generation} of at most "
                    f"{p.max_generations}, best cost {p.best_cost:.5g}, {runs} runs "
                    f"({rate:.0f} runs/s), {now - started:.0f} s")
            frac = p.generation / max(p.max_generations, 1)
            self._later(self._tune_progress, int(1000 * frac), text)

        try:
            tuned = tune_controller(setup, params, progress=progress, systems=systems)
        except Exception as exc:
            stopped = any(isinstance(e, Stopped) for e in error_chain(exc))
            self._later(self._tune_done, None, None if stopped else exc,
                        time.monotonic() - started)
            return
        self._later(self._tune_done, tuned, None, time.monotonic() - started)

    def _later(self, fn: Callable[..., None], *args: Any) -> None:
        try:
            self.doc.add_next_tick_callback(partial(fn, *args))
        except Exception:  # the tab was closed
            pass

    def _tune_progress(self, value: int, text: str) -> None:
        self.w_tune_progress.value = value
        self.w_tune_status.object = html.escape(text)

    def _tune_done(self, tuned: Any, exc: BaseException | None, seconds: float) -> None:
        self.b_tune.disabled = False
        self.b_stop.disabled = True
        if tuned is None:
            if exc is not None:
                self._show_error(exc)
                self.w_tune_status.object = "tuning failed"
            else:
                self.w_tune_status.object = "tuning stopped; the gains are unchanged"
            return
        self.w_tune_progress.value = 1000
        now = (self.settings.controller, self.settings.plant)
        if now != self.tuning:
            self.w_tune_status.object = html.escape(
                f"the tuning of {self.tuning[0]} on the {self.tuning[1]} plant has ended, "
                f"but the page now shows {now[0]} on the {now[1]} plant: its gains "
                f"({', '.join(f'{k}={v:.6g}' for k, v in tuned.gains.items())}) are not "
                f"loaded")
            return
        m = tuned.metrics
        warnings = []
        if not tuned.converged:  # the CLI's warnings, in the page
            warnings.append(f"the search did not converge within {self.w_maxiter.value} "
                            f"generations per stage: raise 'max generations'")
        if not tuned.feasible:
            warnings.append("no gains found that meet the constraints; these are the best "
                            "found")
        for name, side in tuned.at_bounds.items():
            warnings.append(f"{name} ended on its {side} bound")
        self.w_tune_status.object = html.escape(
            f"tuned: {', '.join(f'{k}={v:.6g}' for k, v in tuned.gains.items())}; "
            f"{self.w_objective.value} {tuned.objective_value:.6g}, overshoot "
            f"{m['overshoot']:.3g} %, {tuned.n_evaluations} runs in {seconds:.1f} s. "
            f"Loaded into the sliders.") + "".join(
                f"<br><b>warning:</b> {html.escape(w)}" for w in warnings)
        for name, value in tuned.gains.items():
            if name in self.gain_rows:
                self.gain_rows[name].set(float(value))
        self.submit()
        self.tuned = tuned

    # ------------------------------------------------------------------ fuzzy systems

    def _system_file(self, role: str, event: Any) -> None:
        w = self.w_du_file if role == "du" else self.w_alpha_file
        data: bytes | None = event.new
        if not data:
            return
        try:
            name = upload_name(w.filename, len(data))
        except FuzzyServoError as exc:
            with contextlib.suppress(Exception):
                w.clear()
            self._show_error(exc)
            return
        digest = hashlib.sha256(data).hexdigest()[:12]
        folder = self.workdir / "systems" / digest
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / name
        path.write_bytes(data)
        # the run and the systems tab read it with the command's reader (formats.read_system,
        # through run.load_systems): the same size, nesting and point limits
        self.systems[role] = str(path)
        with contextlib.suppress(Exception):  # the same file may be chosen again later
            w.clear()
        self.submit()
        self._refresh_systems_tab()

    def _paper_systems(self, event: Any = None) -> None:
        self.systems = {}
        self.submit()
        self._refresh_systems_tab()

    def _refresh_systems_tab(self) -> None:
        """Draw the fuzzy systems of the controller: membership functions, control surface and
        rules (the paper's as its rule table)."""
        from ..formats import dumps, read_system
        from ..paper import paper_fuzzy_system
        from ..plots.figures import render_rule_table, rule_table_data
        from ..plots.systems import render_system, system_figure_data

        kind = controller_kind(self.w_controller.value)
        items: list[Any] = []
        if not kind.systems:
            items.append(pn.pane.Markdown(f"The {kind.title} has no fuzzy system."))
        for role in kind.systems:
            path = self.systems.get(role)
            key = (role, path or "paper")
            try:
                if key not in self._figures:
                    if path is None:
                        system = paper_fuzzy_system(role)
                        rules: Any = pn.pane.Matplotlib(
                            render_rule_table(rule_table_data(
                                system, f"{role} rules (paper)")), dpi=64, tight=True,
                            format="png")
                    else:
                        system = read_system(path)
                        lines = [ln.strip() for ln in dumps(system, "fll").splitlines()
                                 if ln.strip().startswith("rule:")]
                        rules = pn.pane.HTML(
                            "<pre style='font-size:12px'>" + html.escape("\n".join(lines))
                            + "</pre>")
                    fig = pn.pane.Matplotlib(render_system(system_figure_data(system, 41)),
                                             dpi=56, tight=True, format="png")
                    self._figures[key] = (rules, fig)
                rules, fig = self._figures[key]
                where = "the paper's (Fig. 3)" if path is None else html.escape(path)
                items += [pn.pane.Markdown(f"### {role} system: {where}"),
                          pn.Row(rules, fig)]
            except Exception as exc:
                items.append(pn.pane.HTML(html.escape(error_line(exc)),
                                          styles={"color": "#842029"}))
        self.systems_view.objects = items

    # ------------------------------------------------------------------ layout

    def _layout(self) -> Any:
        sidebar = pn.Column(
            pn.pane.Markdown("### Controller"), self.w_controller, self.gain_column,
            pn.Card(*self.w_options.values(), title="controller options", collapsed=True,
                    sizing_mode="stretch_width"),
            pn.pane.Markdown("### Plant"), pn.Row(self.w_plant, self.w_set, width=360),
            self.phys_column, self.w_seed,
            pn.pane.Markdown("### Reference and run"), self.w_shape, self.w_step, self.w_spec,
            self.w_load,
            pn.Row(self.w_duration, self.w_ts, self.w_start),
            width=380, styles={"overflow-y": "auto", "overflow-x": "hidden"})
        response = pn.Column(
            self.w_error,
            pn.Row(self.plots, pn.Column(self.w_metrics, pn.Row(self.b_pin, self.b_clear),
                                         self.pin_list, width=550),
                   sizing_mode="stretch_width"),
            self.w_status, pn.Row(self.w_command, self.b_copy, sizing_mode="stretch_width",
                                  min_width=400),
            sizing_mode="stretch_width")
        tuner = pn.Column(
            pn.pane.Markdown(
                "Tune the controller on the page's plant, step, duration, sample time and "
                "delay (`fuzzyservo tune`, docs/model.md, 'Tuning'); the result is loaded "
                "into the sliders."),
            pn.Row(self.w_objective, self.w_maxiter, self.w_restarts, self.w_popsize,
                   self.w_max_os),
            pn.Row(self.b_tune, self.b_stop), self.w_tune_progress, self.w_tune_status,
            self.w_tune_command)
        systems = pn.Column(
            pn.pane.Markdown("Replace a fuzzy system by a .fis, .fcl or .fll file "
                             "(docs/fuzzy-files.md, 'In the loop')."),
            pn.Row(pn.pane.Markdown("Δu system:"), self.w_du_file,
                   pn.pane.Markdown("α system:"), self.w_alpha_file),
            pn.Row(self.w_no_rule, self.b_paper_systems), self.systems_view,
            sizing_mode="stretch_width")
        export = pn.Column(
            pn.pane.Markdown("Download what the page shows; the command beside the plots "
                             "makes the same run."),
            self.d_gains, self.d_csv, self.d_c, self.d_st, self.d_fmu)
        self.tabs = pn.Tabs(("Response", response), ("Tune", tuner), ("Fuzzy systems", systems),
                            ("Export", export), dynamic=False, sizing_mode="stretch_width",
                            css_classes=["fs-tabs"])
        self.tabs.param.watch(self._tab_changed, "active")
        return pn.Row(sidebar, self.tabs, sizing_mode="stretch_width")

    def _tab_changed(self, event: Any) -> None:
        if event.new == 2:
            self._refresh_systems_tab()
