"""The sweep spec: everything checked before a run, one clear line per mistake."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fuzzyservo.cli import main
from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.sweep import load_spec, parse_spec

CTL = [{"controller": "pi", "gains": {"kp": 1.0, "ki": 0.5}}]
EXAMPLE = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data/sweeps/example.toml"


def _doc(**parts: object) -> dict:
    doc: dict = {"sweep": {}, "controllers": CTL}
    doc.update(parts)
    return doc


def test_example_spec_uses_every_kind_of_variation(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", "--example"]) == 0
    text = capsys.readouterr().out
    assert text == EXAMPLE.read_text(encoding="utf-8")
    spec = load_spec(EXAMPLE)
    dists = {v.distribution for v in spec.random}
    assert dists == {"uniform", "log-uniform", "normal", "log-normal"}
    names = {v.name for v in spec.vary}
    assert {"delay", "amplitude", "noise_std", "load.external_force"} <= names
    assert any(v.is_grid for v in spec.vary) and any(v.relative for v in spec.vary)
    assert 200 <= spec.n_runs <= 1000


@pytest.mark.parametrize(("doc", "message"), [
    (_doc(sweep={"plant": "cubic"}), "sweep.plant: must be one of linear"),
    (_doc(sweep={"samples": 0}), r"sweep.samples: must be an integer in \[1"),
    (_doc(sweep={"start": 1.5}), r"sweep.start: must be a fraction of the stroke in \(0, 1\)"),
    (_doc(sweep={"colour": 1}), "sweep: unknown key 'colour'"),
    (_doc(vary=[{"name": "load.weight", "grid": [1.0]}]), "vary.0..name: 'load.weight' is"),
    (_doc(vary=[{"name": "load.mass", "distribution": "cauchy"}]),
     "vary.0..distribution: must be one of uniform, log-uniform, normal, log-normal"),
    (_doc(vary=[{"name": "load.mass", "distribution": "normal", "mean": 1.0}]),
     "a normal distribution needs mean and std"),
    (_doc(vary=[{"name": "load.mass", "distribution": "uniform", "low": 2.0, "high": 1.0}]),
     "needs low < high"),
    (_doc(vary=[{"name": "load.mass", "distribution": "uniform", "low": 1.0, "high": 2.0,
                 "std": 1.0}]), "does not apply to a uniform distribution"),
    (_doc(vary=[{"name": "delay", "relative": True, "grid": [1.0]}]),
     "delay is varied in absolute SI values"),
    (_doc(vary=[{"name": "load_force", "grid": [100.0]}]),
     "the linear plant has no load-force input"),
    (_doc(vary=[{"name": "load.mass", "grid": [1.0, 1.0]}]), "has a value twice"),
    (_doc(vary=[{"name": "delay", "grid": [0.0]}, {"name": "delay", "grid": [0.1]}]),
     "delay is varied twice"),
    (_doc(reference={"spec": "sine:0.1:5"}, vary=[{"name": "amplitude", "grid": [0.1]}]),
     "amplitude varies a step reference"),
    (_doc(sweep={"samples": 3}), "would repeat identical runs"),
    ({"sweep": {}, "controllers": []}, "give at least one"),
    ({"sweep": {}, "controllers": [{"controller": "pi", "gains": {"kp": -1.0}}]},
     "controllers.0..gains"),
    ({"sweep": {}, "controllers": [CTL[0], CTL[0]]}, "label 'pi' is used twice"),
    ({"sweep": {}, "controllers": [{"controller": "pi", "gains": {"kp": 1.0, "ki": 1.0},
                                    "options": {"de_per": "second"}}]},
     "controller pi takes no option 'de_per'"),
    ({"sweep": {"ts": 0.002}, "controllers": [{"gains": "linear-stfpi.toml"}]},
     "was tuned at ts = 0.001 s, the sweep runs at ts = 0.002 s"),
    ({"sweep": {}, "controllers": [{"gains": "no-such-file.toml"}]}, "no file 'no-such-file"),
    (_doc(vary=[{"name": "noise_std", "grid": [-1e-3, 0.0]}]), "noise_std must be >= 0"),
    (_doc(vary=[{"name": "delay", "distribution": "normal", "mean": 0.01, "std": 0.01}]),
     "delay must be >= 0: give low >= 0"),
    (_doc(vary=[{"name": "transducer.noise_std", "grid": [1e-6]}]),
     "does nothing in the loop: vary noise_std"),
    (_doc(vary=[{"name": "delay.transport_delay", "grid": [0.01]}]),
     "does nothing in the loop: vary delay"),
    (_doc(overrides={"transducer.noise_std": 1e-6}), "set .sweep. noise_std"),
    (_doc(metrics={"settle_band": 0.05}), "spec: unknown key 'metrics'"),
    (_doc(sweep={"delay": 5.0, "duration": 1.0}), "sweep.delay: .*1"),
    (_doc(reference={"spec": "step:5.0"}), "reference.spec: .*stroke"),
])
def test_bad_specs_are_refused_naming_the_key(doc: dict, message: str) -> None:
    message = message.replace("vary.0.", r"vary\[0\]").replace("controllers.0.",
                                                               r"controllers\[0\]")
    with pytest.raises(ParameterError, match=message):
        parse_spec(doc)


def test_cli_refuses_a_bad_spec_in_one_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "s.toml"
    spec.write_text('[sweep]\nplant = "linear"\nsamples = -1\n[[controllers]]\n'
                    'controller = "pi"\ngains = { kp = 1.0 }\n', encoding="utf-8")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert re.search(r"s\.toml'?: sweep\.samples: must be an integer in \[1, \d+\], got -1", err)
    assert not (tmp_path / "o").exists()
    spec.write_text("[sweep\n", encoding="utf-8")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    assert "is not valid TOML" in capsys.readouterr().err


def test_spec_file_errors() -> None:
    with pytest.raises(InputError, match="is a directory"):
        load_spec(EXAMPLE.parent)


def test_digest_names_everything_the_results_depend_on() -> None:
    base = parse_spec(_doc())
    assert parse_spec(_doc()).digest == base.digest
    for change in ({"sweep": {"seed": 1}}, {"sweep": {"duration": 4.0}},
                   {"controllers": [{"controller": "pi", "gains": {"kp": 1.0, "ki": 0.6}}]},
                   {"vary": [{"name": "delay", "grid": [0.0, 0.01]}]}):
        assert parse_spec(_doc(**change)).digest != base.digest


def test_manifest_record_rebuilds_the_same_spec() -> None:
    from fuzzyservo.sweep import SweepSpec

    spec = load_spec(EXAMPLE)
    again = SweepSpec.from_canonical(spec.canonical())
    assert again.digest == spec.digest
    assert again.n_points == spec.n_points
    assert [c.build(spec.ts).pack().tolist() for c in again.controllers] == \
        [c.build(spec.ts).pack().tolist() for c in spec.controllers]


def test_digest_follows_the_content_of_every_file_read(tmp_path: Path) -> None:
    src = Path(__file__).resolve().parents[2] / "src/fuzzyservo/data"
    for name in ("gains/linear-stfpi.toml", "systems/paper-du.fis"):
        (tmp_path / Path(name).name).write_bytes((src / name).read_bytes())
    doc = {"sweep": {}, "controllers": [{"gains": "linear-stfpi.toml",
                                         "du_system": "paper-du.fis"}]}
    first = parse_spec(doc, base_dir=tmp_path).digest
    fis = tmp_path / "paper-du.fis"
    fis.write_text(fis.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    second = parse_spec(doc, base_dir=tmp_path).digest
    gains = tmp_path / "linear-stfpi.toml"
    gains.write_text(gains.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    third = parse_spec(doc, base_dir=tmp_path).digest
    assert len({first, second, third}) == 3
