"""Parameter objects: validation, overrides, TOML files (issue 3, point 7)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from fuzzyservo.errors import InputError, ParameterError
from fuzzyservo.paper import paper_params
from fuzzyservo.plant import (
    CylinderParams,
    FluidParams,
    LoadParams,
    ValveParams,
    allowed_names,
    load_toml,
    to_dict,
    with_overrides,
)


@pytest.fixture(scope="module")
def paper():  # type: ignore[no-untyped-def]
    return paper_params()


def test_areas_from_table_a1(paper) -> None:  # type: ignore[no-untyped-def]
    c = paper.cylinder
    # exact geometry; rel 1e-12 is rounding only
    assert c.piston_area == pytest.approx(math.pi / 4 * 0.1127**2, rel=1e-12)
    assert c.ring_area == pytest.approx(math.pi / 4 * (0.1127**2 - 0.0704**2), rel=1e-12)
    # model notes §4.1 quote A_f = 9.9756e-3 m², A_n = 6.0830e-3 m² to 5 digits
    assert c.piston_area == pytest.approx(9.9756e-3, rel=1e-4)
    assert c.ring_area == pytest.approx(6.0830e-3, rel=1e-4)


def test_orifice_coefficient_gives_rated_no_load_flow(paper) -> None:  # type: ignore[no-untyped-def]
    # no-load extension: Q = G sqrt(P_s/(1+r³)) must be the rated flow; rel 1e-12 is rounding
    r = paper.cylinder.area_ratio
    q = paper.orifice_coefficient * math.sqrt(paper.supply.pressure / (1 + r**3))
    assert q == pytest.approx(2.613e-3, rel=1e-12)
    # model notes §4.3: W x_v,max = 3.74e-5 m² with C_d = 0.61 (3 printed digits)
    assert paper.spool_area_gradient == pytest.approx(3.74e-5, rel=5e-3)


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda: CylinderParams(bore=0.1, rod_diameter=0.1, stroke=1.0), "rod_diameter"),
        (lambda: CylinderParams(bore=0.1, rod_diameter=0.12, stroke=1.0), "smaller than"),
        (lambda: CylinderParams(bore=0.1, rod_diameter=0.05, stroke=0.0), "stroke"),
        (lambda: LoadParams(mass=0.0), "load.mass"),
        (lambda: LoadParams(mass=-3.0), "-3.0"),
        (lambda: FluidParams(oil_bulk_modulus=0.0), "fluid.oil_bulk_modulus"),
        (lambda: FluidParams(density=float("nan")), "fluid.density"),
        (lambda: ValveParams(rated_flow=1e-3, omega_v=600.0, zeta_v=0.3,
                             discharge_coefficient=1.2), "(0, 1]"),
        (lambda: ValveParams(rated_flow=1e-3, omega_v=600.0, zeta_v=0.3,
                             discharge_coefficient=0.0), "discharge_coefficient"),
        (lambda: LoadParams(mass=1.0, coulomb_friction=10.0, static_friction=5.0),
         "static_friction"),
    ],
)
def test_impossible_parameters_raise(make, needle: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=None) as info:
        make()
    assert needle in str(info.value)


def test_negative_delay_and_volumes(paper) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=r"delay.transport_delay must be >= 0, got -0.001"):
        with_overrides(paper, {"delay.transport_delay": -0.001})
    with pytest.raises(ParameterError, match="fluid.hose_volume"):
        with_overrides(paper, {"fluid.hose_volume": 0.0})


def test_unknown_name_lists_allowed(paper) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError) as info:
        with_overrides(paper, {"valve.nul_leakage": 0.0})
    msg = str(info.value)
    assert "valve.nul_leakage" in msg and "valve.null_leakage" in msg
    assert "load.coulomb_friction" in msg


def test_issue_field_names_exist() -> None:
    names = allowed_names()
    for n in ("valve.null_leakage", "cylinder.internal_leakage", "load.coulomb_friction",
              "load.static_friction", "load.viscous_damping"):
        assert n in names


def test_overrides_validate_once(paper) -> None:  # type: ignore[no-untyped-def]
    # static below coulomb only transiently: applied together it is valid
    p = with_overrides(paper, {"load.static_friction": 0.0, "load.coulomb_friction": 0.0})
    assert p.load.coulomb_friction == 0.0 and p.load.static_friction == 0.0
    assert p.cylinder == paper.cylinder


def test_toml_round_trip(tmp_path: Path, paper) -> None:  # type: ignore[no-untyped-def]
    import tomli_w

    d = to_dict(paper)
    d["load"]["mass"] = 1234.0
    f = tmp_path / "set.toml"
    f.write_bytes(tomli_w.dumps(d).encode())
    p = load_toml(f, paper)
    assert p == replace(paper, load=replace(paper.load, mass=1234.0))


def test_toml_errors(tmp_path: Path, paper) -> None:  # type: ignore[no-untyped-def]
    bad = tmp_path / "bad.toml"
    bad.write_text("[valve\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_toml(bad, paper)
    with pytest.raises(InputError, match="cannot read"):
        load_toml(tmp_path / "missing.toml", paper)
    grp = tmp_path / "grp.toml"
    grp.write_text("[valves]\nrated_flow = 1.0\n")
    with pytest.raises(ParameterError, match="unknown parameter group 'valves'"):
        load_toml(grp, paper)
    rod = tmp_path / "rod.toml"
    rod.write_text("[cylinder]\nrod_diameter = 0.2\n")
    with pytest.raises(ParameterError, match="rod_diameter"):
        load_toml(rod, paper)
