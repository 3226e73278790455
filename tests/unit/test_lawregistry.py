"""The registry of the built-in viscoplastic laws (app/model/lawregistry.py): each law's
LawSpec is the one declaration the case layer, the run log and the blow-up bound read.  The
schema's keys, the rules' messages and kappa's growth bounds are checked against values
written out here by hand, not against the registry's own output."""
from __future__ import annotations

import math
import pickle
import re

import pytest

from conftest import paper_raw
from vpcontact.case import validate
from vpcontact.case.schema import SCHEMA
from vpcontact.io.errors import CaseError
from vpcontact.model import lawregistry
from vpcontact.model.chaboche import Chaboche
from vpcontact.model.lawregistry import LAWS, kappa_growth, key_owners, key_schemas
from vpcontact.model.lawspec import POSITIVE, LawKey, LawSpec
from vpcontact.model.norton import Norton
from vpcontact.model.viscoplastic import Perzyna, PowerLaw
from vpcontact.post.linefigures import _kappa_unit

VP = SCHEMA["properties"]["material"]["properties"]["viscoplastic"]["properties"]
SECTIONS = {"perzyna": {"lambda1": 100.0, "lambda2": 50.0},
            "power": {"law": "power", "lambda1": 100.0, "lambda2": 50.0, "s_ref": 2.0},
            "norton": {"law": "norton", "A": 1e-6, "n": 3},
            "chaboche": {"law": "chaboche", "k": 10.0, "K": 20.0, "n": 3, "C": 2000.0,
                         "gamma": 50.0, "Q": 5.0, "b": 10.0}}
CLASSES = {"perzyna": Perzyna, "power": PowerLaw, "norton": Norton, "chaboche": Chaboche}


def _case(vp: dict, **material):
    raw = paper_raw()
    raw["material"]["viscoplastic"] = vp
    raw["material"].update(material)
    return validate(raw, "t.yaml")


def _refusal(vp: dict, **material) -> str:
    """The message of a refused section, without the YAML line numbers."""
    with pytest.raises(CaseError) as info:
        _case(vp, **material)
    return re.sub(r" \(line \d+\)", "", str(info.value))


def test_the_schema_lists_every_law_and_its_keys():
    assert VP["law"]["enum"] == ["perzyna", "power", "norton", "chaboche", "python"]
    assert set(VP) == {"kappa0", "law", "class", "params", "lambda1", "lambda2", "n", "s_ref",
                       "A", "k", "K", "C", "gamma", "Q", "b"}
    assert {k: {a: b for a, b in VP[k].items() if a != "description"} for k in ("n", "Q", "k")} \
        == {"n": {"type": "number", "minimum": 1}, "Q": {"type": "number"},
            "k": {"type": "number", "minimum": 0}}
    assert "default" not in VP["n"]           # power's n = 1 is filled by the Case, not here
    assert VP["lambda1"]["description"].startswith("laws perzyna and power (required there)")
    assert VP["n"]["description"].startswith("law power (absent: 1): ")


def test_key_owners():
    assert key_owners() == {"lambda1": ("perzyna", "power"), "lambda2": ("perzyna", "power"),
                            "n": ("power", "norton", "chaboche"), "s_ref": ("power",),
                            "A": ("norton",), "k": ("chaboche",), "K": ("chaboche",),
                            "C": ("chaboche",), "gamma": ("chaboche",), "Q": ("chaboche",),
                            "b": ("chaboche",)}


@pytest.mark.parametrize("law", list(SECTIONS))
def test_each_law_from_its_section(law):
    case = _case(SECTIONS[law])
    vp = case.material.viscoplastic
    built = lawregistry.viscoplastic_law(vp, _elasticity())
    assert type(built) is CLASSES[law] and built.name == law
    given = {k: float(v) for k, v in SECTIONS[law].items() if k != "law"}
    assert {k: v for k, (v, _) in built.constants().items()} == \
        {**given, **({"n": 1.0} if law == "power" else {})}
    assert vp.constants == {k: v for k, (v, _) in built.constants().items()}


# what each law's required keys are, as the messages said before the registry
REQUIRED = {"perzyna": {"lambda1": "the viscosity of G, in N s/m^2",
                        "lambda2": "the viscosity of Gk, in s"},
            "norton": {"A": "the coefficient of eps_vp' = A sigma_eq^n N, in Pa^-n s^-1",
                       "n": "the exponent n >= 1 of sigma_eq^n"},
            "chaboche": {"k": "the initial yield stress, in Pa", "K": "the drag stress, in Pa",
                         "n": "the exponent n >= 1 of <f/K>^n",
                         "C": "the kinematic modulus, in Pa", "gamma": "the dynamic recovery",
                         "Q": "the saturated isotropic hardening, in Pa",
                         "b": "the isotropic rate"}}
REQUIRED["power"] = {**REQUIRED["perzyna"], "s_ref": "the stress scale of the overstress r = "
                                                    "||sigma - P sigma||_VM / s_ref, in Pa"}


@pytest.mark.parametrize("law", list(SECTIONS))
def test_each_required_key_and_each_foreign_key(law):
    for key, what in REQUIRED[law].items():
        section = {k: v for k, v in SECTIONS[law].items() if k != key}
        assert _refusal(section) == \
            f"t.yaml: material.viscoplastic.{key}: required with law {law} ({what})"
    for key, owners in (("s_ref", "law power"), ("A", "law norton"),
                        ("lambda2", "laws perzyna, power"), ("n", "laws power, norton, chaboche")):
        if law not in owners:
            assert _refusal({**SECTIONS[law], key: 1.0}) == \
                f"t.yaml: material.viscoplastic.{key}: not used with law {law} (only with {owners})"


def test_the_case_holds_the_constants_by_attribute_too():
    vp = _case(SECTIONS["chaboche"]).material.viscoplastic
    assert (vp.law, vp.K, vp.Q, vp.lambda1, vp.s_ref) == ("chaboche", 20.0, 5.0, None, None)
    with pytest.raises(AttributeError):
        _ = vp.not_a_key
    assert pickle.loads(pickle.dumps(vp)) == vp          # a Case crosses processes
    assert _case(SECTIONS["power"]).material.viscoplastic.n == 1.0


def test_titles():
    terms = [_case(SECTIONS[law]).active_terms()[1] for law in ("perzyna", "power", "norton")]
    assert terms[0].startswith("Perzyna viscoplastic history")
    assert terms[1].startswith("power-law Perzyna (n = 1, s_ref = 2) viscoplastic")
    assert terms[2].startswith("Norton (A = 1e-06, n = 3) viscoplastic")


def test_kappa_growth_closed_forms():
    """By hand: Perzyna 2 T S / (3 lambda2); the power law times (S / s_ref)^(n-1) for
    S > s_ref; Norton T A S^n; Chaboche max(S, |Q|, T (2 S / K)^n); a user's law inf."""
    T, S = 2.0, 30.0
    cases = {law: _case(SECTIONS[law]).material.viscoplastic for law in SECTIONS}
    assert kappa_growth(cases["perzyna"], T, S) == pytest.approx(2 * 2 * 30 / (3 * 50))
    power = _case({**SECTIONS["power"], "n": 3.0}).material.viscoplastic
    assert kappa_growth(power, T, S) == pytest.approx(0.8 * 15.0 ** 2)
    assert kappa_growth(power, T, 1.0) == pytest.approx(2 * 2 * 1 / (3 * 50))   # r < 1
    assert kappa_growth(cases["norton"], T, S) == pytest.approx(2 * 1e-6 * 27000)
    assert kappa_growth(cases["chaboche"], T, S) == pytest.approx(2 * 3.0 ** 3)   # 54 > S
    assert kappa_growth(cases["chaboche"], T, 5.0) == 5.0                  # S = |Q| = 5
    huge = _case({**SECTIONS["power"], "n": 400.0}).material.viscoplastic
    assert kappa_growth(huge, T, 1e6) == math.inf                          # overflows
    user = _case({"law": "python", "class": "X"}).material.viscoplastic
    assert kappa_growth(user, T, S) == math.inf


def test_plane_strain_rules_come_from_the_specs():
    voigt = {"voigt": [[1400, 600, 0], [600, 1400, 0], [0, 0, 400]]}
    assert [law for law, spec in LAWS.items() if spec.carries_sigma33] == ["norton", "chaboche"]
    raw = paper_raw()
    raw["material"] = {"elasticity": voigt, "plane": "strain", "viscoplastic": SECTIONS["norton"]}
    with pytest.raises(CaseError, match="law norton in plane strain .* needs an isotropic E"):
        validate(raw, "t.yaml")
    assert _refusal({**SECTIONS["norton"], "kappa0": 0.5}, plane="strain") == (
        "t.yaml: material.viscoplastic.kappa0: law norton in plane strain (material.plane: "
        "strain) starts from p = 0, eps_vp33 = 0 (allowed: 0 or absent)")
    _case({**SECTIONS["norton"], "kappa0": 0.5})                       # plane stress: a p0
    assert _refusal({**SECTIONS["chaboche"], "Q": -11.0}) == (
        "t.yaml: material.viscoplastic.Q: k + Q must be >= 0 (the yield radius k + R tends "
        "to k + Q), got -1")


def test_kappa_units_of_the_figures():
    assert _kappa_unit({"material": {"viscoplastic": {"lambda1": 1.0}}}) == " [N/m^2]"
    assert _kappa_unit({"material": {"viscoplastic": {"law": "norton"}}}) == " [-]"
    assert _kappa_unit({"material": {"viscoplastic": {"law": "python"}}}) == ""


def test_a_new_law_is_one_spec(monkeypatch):
    """A law added to the registry brings its keys, their owners and the law's sentence."""
    spec = LawSpec(name="toy", title="Toy", summary="a toy", kappa0="unused",
                   kappa_unit="-", keys={"tau": LawKey(POSITIVE, "a time, in s", "s"),
                                         "n": LawKey({"type": "number", "minimum": 1},
                                                     "the toy's exponent", "-", 2.0)},
                   build=lambda vp, el, plane: None, kappa_growth=lambda vp, T, S: 0.0)
    monkeypatch.setitem(LAWS, "toy", spec)
    assert key_owners()["n"] == ("power", "norton", "chaboche", "toy")
    assert key_schemas()["tau"]["description"] == "law toy (required there): a time, in s"
    assert "law toy (absent: 2): the toy's exponent" in key_schemas()["n"]["description"]
    assert "toy, a toy;" in lawregistry.law_description("user")
    clash = LawSpec(**{**spec.__dict__, "name": "clash",
                       "keys": {"n": LawKey(POSITIVE, "another n", "-")}})
    monkeypatch.setitem(LAWS, "clash", clash)
    with pytest.raises(ValueError, match="declare different schemas"):
        key_schemas()


def _elasticity():
    from vpcontact.model.material import Elasticity
    return Elasticity(1000.0, 0.4, 2)


def test_stress_scaling_of_the_stability_sweep():
    """sigma -> 10 sigma with u and the creep strain unchanged: E, lambda1, kappa0, s_ref, k,
    K, C, Q times 10; Norton's A times 10^-n (A sigma_eq^n unchanged); a user's law: none."""
    from vpcontact.studies.variantsections import scaled_material
    power = {"E": 1.0, "viscoplastic": {**SECTIONS["power"], "kappa0": 0.5}}
    assert scaled_material("material", power, 10.0)[0] == {
        "material.E": ("scale", 10.0), "material.viscoplastic.lambda1": ("scale", 10.0),
        "material.viscoplastic.kappa0": ("scale", 10.0),
        "material.viscoplastic.s_ref": ("scale", 10.0)}
    norton = scaled_material("material", {"E": 1.0, "viscoplastic": SECTIONS["norton"]}, 10.0)
    assert norton[0]["material.viscoplastic.A"][1] == pytest.approx(1e-3)
    chaboche = scaled_material("material", {"viscoplastic": SECTIONS["chaboche"]}, 2.0)[0]
    assert sorted(k.split(".")[-1] for k in chaboche) == ["C", "K", "Q", "k"]
    assert scaled_material("material", {"E": 1.0, "viscoplastic": {"law": "python"}}, 2.0) \
        == ({}, "python's law: its parameters' units are unknown")
