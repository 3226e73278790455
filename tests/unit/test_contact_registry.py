"""The registries of the built-in contact laws (app/model/contactregistry.py): each law's
ContactLawSpec is the one declaration the schema, the rules, the Case's tagged sections,
the blow-up levels and the builders read.  The schema's keys, the rules' messages and the
built laws' values are checked against values written out here by hand; a toy law of each
kind, added to its registry in the test, is accepted, refused and built with no other
change (the proof that a new contact law is one module)."""
from __future__ import annotations

import copy
import re

import numpy as np
import pytest

from conftest import paper_raw
from vpcontact.case import schemamemo, validate
from vpcontact.case.model import Compliance, Coulomb, Friction, Memory, Slip
from vpcontact.case.pairrules import MEMORY_SHAPE
from vpcontact.case.schema import SCHEMA
from vpcontact.io.errors import CaseError
from vpcontact.model import contactregistry as registry
from vpcontact.model.contact_laws import (
    NormalCompliance,
    PiecewiseLinearFriction,
    PowerCompliance,
    SlipWeakening,
    TableSlip,
    space_field,
    varies_in_space,
)
from vpcontact.model.contact_tables import TableCompliance, TableFriction
from vpcontact.model.contactregistry import BOUNDS, COULOMBS, KERNELS, NORMALS, SLIPS
from vpcontact.model.contactspec import (
    EXPRESSION,
    NONNEGATIVE,
    POSITIVE,
    ContactKey,
    ContactLawSpec,
)
from vpcontact.model.coulomb import CoulombLaw
from vpcontact.model.gamma3 import section_kernel, section_slip
from vpcontact.model.memory_kernels import ExponentialKernel, PowerKernel, TableKernel
from vpcontact.post.divergence import _law_levels

CONTACT = SCHEMA["properties"]["contact"]["properties"]
SECTIONS = {"memory": CONTACT["memory"]["properties"],
            "normal_compliance": CONTACT["normal_compliance"]["properties"],
            "friction": CONTACT["friction"]["properties"],
            "slip": CONTACT["friction"]["properties"]["slip"]["properties"],
            "coulomb": CONTACT["friction"]["properties"]["coulomb"]["properties"]}
REGISTRIES = {"memory": KERNELS, "normal_compliance": NORMALS, "friction": BOUNDS,
              "slip": SLIPS, "coulomb": COULOMBS}
LAW42 = {"b": 1.0, "c1": 60.0, "c2": 60.0, "u1": 0.01}


def _case(**contact):
    """The paper's case with its contact section's laws replaced (None: removed)."""
    raw = paper_raw()
    for key, value in contact.items():
        if value is None:
            raw["contact"].pop(key, None)
        else:
            raw["contact"][key] = copy.deepcopy(value)
    return validate(raw, "t.yaml")


def _refusal(**contact) -> str:
    """The message of a refused contact section, without the YAML line numbers."""
    with pytest.raises(CaseError) as info:
        _case(**contact)
    return re.sub(r" \(line \d+\)", "", str(info.value))


def test_the_registries_hold_the_built_in_laws():
    assert list(KERNELS) == ["exponential", "power", "table"]
    assert {n: list(s.keys) for n, s in KERNELS.items()} == \
        {"exponential": ["beta"], "power": ["alpha", "tau"], "table": ["table"]}
    assert {n: list(s.keys) for n, s in SLIPS.items()} == \
        {"weakening": ["theta_inf", "s0"], "table": ["table"]}
    assert {n: list(s.keys) for n, s in NORMALS.items()} == \
        {"power": ["c_nu", "m"], "table": ["table"]}
    assert {n: list(s.keys) for n, s in BOUNDS.items()} == \
        {"4.2": ["b", "c1", "c2", "u1"], "table": ["table"]}
    assert {n: list(s.required()) for n, s in COULOMBS.items()} == \
        {"mu": ["mu"], "static/kinetic": ["mu_s", "mu_k", "slip_length"]}
    assert [k for k, s in KERNELS.items() if s.recursive] == ["exponential"]
    assert MEMORY_SHAPE == ("kernel", "beta", "alpha", "tau", "table", "sum")


@pytest.mark.parametrize("section", list(SECTIONS))
def test_every_law_key_is_in_the_schema_as_declared(section):
    for spec in REGISTRIES[section].values():
        for key, use in spec.keys.items():
            assert SECTIONS[section][key] is use.schema, (section, key)


def test_the_schema_of_the_laws_keys_in_the_users_order():
    """The order and words of docs/case-file.md: the default kernel's keys, kernel, the
    others; the laws' keys before slip, coulomb and the user's law."""
    assert list(SECTIONS["memory"]) == ["b0", "beta", "kernel", "alpha", "tau", "table", "sum"]
    assert SECTIONS["memory"]["kernel"] == {
        "enum": ["exponential", "power", "table"], "default": "exponential",
        "description": "b(t) = b0 exp(-beta t), b0 (1 + t/tau)^-alpha, or b0 times the "
                       "piecewise-linear table"}
    assert SECTIONS["memory"]["sum"]["description"].startswith(
        "auto: exact O(1) recursion for the exponential kernel, stored")
    assert SECTIONS["memory"]["beta"]["default"] == 0.0
    assert list(SECTIONS["normal_compliance"]) == ["c_nu", "m", "table", "law", "class",
                                                   "params"]
    assert list(SECTIONS["friction"]) == ["b", "c1", "c2", "u1", "table", "slip", "coulomb",
                                          "law", "class", "params"]
    assert list(SECTIONS["slip"]) == ["theta_inf", "s0", "table"]
    assert list(SECTIONS["coulomb"]) == ["mu", "mu_s", "mu_k", "slip_length"]
    assert SECTIONS["coulomb"]["mu_k"] == {"type": "number", "description": "the kinetic "
                                           "coefficient (dimensionless, 0 <= mu_k <= mu_s): "
                                           "mu(s) for s >= slip_length"}
    assert SECTIONS["friction"]["u1"] == {"type": "number", "exclusiveMinimum": 0,
                                          "description": "slip where softening turns into "
                                                         "hardening [m]"}


def test_the_case_holds_tagged_sections():
    c = _case(normal_compliance={"c_nu": 200, "m": 2},
              friction={**LAW42, "slip": {"table": [[0, 1], [0.01, 0.5]]}},
              memory={"b0": 3, "kernel": "power", "alpha": 0.5, "tau": 2}).contact
    assert c.normal == Compliance("power", {"c_nu": 200.0, "m": 2.0})
    assert (c.c_nu, c.normal.m, c.normal.table) == (200.0, 2.0, None)
    assert c.friction == Friction("4.2", LAW42, Slip("table", {"table": ((0.0, 1.0),
                                                                         (0.01, 0.5))}))
    assert (c.friction.u1, c.friction.table, c.friction.slip.s0) == (0.01, None, None)
    assert c.memory == Memory(3.0, "power", {"alpha": 0.5, "tau": 2.0}, "auto")
    assert c.memory.beta is None and c.memory.alpha == 0.5
    with pytest.raises(AttributeError):
        _ = c.memory.gamma
    tables = _case(normal_compliance={"table": [[0, 0], [0.01, 1]]},
                   friction={"table": [[0, 1], [0.01, 0.5], [0.02, 0.6]]}).contact
    assert tables.normal.law == "table" and tables.c_nu is None
    assert tables.friction.law == "table" and tables.friction.b is None
    coulomb = _case(friction={"coulomb": {"mu": 0.3}}).contact.friction
    assert coulomb.law is None and coulomb.b is None and coulomb.coulomb.mu == 0.3
    assert coulomb.coulomb == Coulomb("mu", {"mu": 0.3}) and coulomb.coulomb.mu_k is None
    assert coulomb.coulomb.title == "Coulomb friction mu p_n (mu = 0.3)"
    sk = _case(friction={"coulomb": {"mu_s": 0.4, "mu_k": 0.3, "slip_length": 2e-4}})
    c = sk.contact.friction.coulomb
    assert c == Coulomb("static/kinetic", {"mu_s": 0.4, "mu_k": 0.3, "slip_length": 2e-4})
    assert (c.mu, c.mu_s, c.mu_k, c.slip_length) == (0.4, 0.4, 0.3, 2e-4)
    assert c.has_slip and not coulomb.coulomb.has_slip
    assert ("Coulomb friction mu(s) p_n (mu_s = 0.4, mu_k = 0.3 over slip length 0.0002 m s)"
            in sk.active_terms())
    theta = section_slip(sk.contact.friction).theta(np.array([0.0, 1e-4, 1.0]))
    assert theta.tolist() == [1.0, 1.0 - (1.0 - 0.3 / 0.4) * 0.5, 0.3 / 0.4]
    assert section_slip(coulomb) is None


def test_each_law_built_from_its_section():
    c = _case(normal_compliance={"c_nu": 200.0, "m": 2.0},
              friction={"table": [[0, 1], [0.01, 0.5], [0.02, 0.6]],
                        "slip": {"theta_inf": 0.4, "s0": 0.01}},
              memory={"b0": 3.0, "kernel": "table", "table": [[0, 1], [1, 0]]}).contact
    law = registry.contact_law(c, 1e-7)
    assert law.normal == PowerCompliance(200.0, 2.0)
    assert isinstance(law.friction, TableFriction)
    assert law.friction.derivative(np.array([0.005]))[0] == pytest.approx(0.75, rel=1e-15)
    assert registry.slip_law(c.friction.slip) == SlipWeakening(0.4, 0.01)
    kernel = section_kernel(c.memory)
    assert isinstance(kernel, TableKernel) and kernel(0.25) == pytest.approx(2.25, rel=1e-15)
    paper = _case().contact
    assert registry.contact_law(paper, 1e-7).normal == NormalCompliance(100.0)
    assert registry.contact_law(paper, 1e-7).friction == PiecewiseLinearFriction(1.0, 60.0,
                                                                                 60.0, 0.01)
    tables = _case(normal_compliance={"table": [[0, 0], [0.01, 1]]},
                   friction={**LAW42, "slip": {"table": [[0, 1], [0.01, 0.5]]}}).contact
    assert isinstance(registry.contact_law(tables, 1e-7).normal, TableCompliance)
    assert isinstance(registry.slip_law(tables.friction.slip), TableSlip)
    assert section_kernel(_case(memory={"b0": 2.0, "beta": 1.5}).contact.memory) == \
        ExponentialKernel(2.0, 1.5)
    assert registry.memory_kernel("power", 2.0, alpha=0.7, tau=0.3) == PowerKernel(2.0, 0.7,
                                                                                   0.3)


def test_stress_levels_of_the_blow_up_bound():
    """c_nu r^m, the compliance table's largest p, b0 T r (the table kernel's largest value
    too), the bound's constants (4.2): b, c1 u1, c2 u1; a table's |tau|."""
    c = _case(normal_compliance={"c_nu": 100.0, "m": 2.0}, friction=LAW42,
              memory={"b0": 3.0, "kernel": "table", "table": [[0, 1], [1, 5]]}).contact
    assert _law_levels(c, 2.0, 0.1) == pytest.approx([100.0 * 0.1**2, 5.0 * 2.0 * 0.1,
                                                      1.0, 0.6, 0.6], rel=1e-15)
    tables = _case(normal_compliance={"table": [[0, 0], [0.01, 1], [0.02, 3]]},
                   friction={"table": [[0, 1], [0.01, 0.5], [0.02, 0.6]]}).contact
    assert _law_levels(tables, 1.0, 0.1) == [3.0, 1.0, 0.5, 0.6]


@pytest.mark.parametrize("contact, message", [
    ({"friction": {**LAW42, "table": [[0, 1], [1, 1]]}},
     "contact.friction.table: not with b, c1, c2, u1 (give b, c1, c2, u1, or table; not "
     "both)"),
    ({"friction": {"b": 1.0, "c1": 1.0}},
     "contact.friction.c2: required (give b, c1, c2, u1, or table)"),
    ({"friction": {**LAW42, "slip": {"theta_inf": 0.3}}},
     "contact.friction.slip.s0: required (give theta_inf, s0, or table)"),
    ({"normal_compliance": {"table": [[0, 0], [1, 1]], "m": 2}},
     "contact.normal_compliance.m: only with c_nu (a table gives p(r) itself)"),
    ({"normal_compliance": {"law": "python", "class": "P", "c_nu": 1.0, "m": 2}},
     "contact.normal_compliance.c_nu: not with law: python (the user's class gives the "
     "law; remove c_nu, m)"),
    ({"memory": {"b0": 1.0, "kernel": "power", "alpha": 1.0}},
     "contact.memory.tau: required for the power kernel"),
    ({"memory": {"b0": 1.0, "kernel": "table", "table": [[0, 1], [1, 0]], "sum": "recursion"}},
     "contact.memory.sum: the recursion is exact only for the exponential kernel (allowed "
     "here: auto, direct)"),
    ({"friction": {"b": 0.1, "c1": 60.0, "c2": 1.0, "u1": 0.01}},
     "contact.friction: b - c1 u1 must be >= 0"),
    ({"friction": {**LAW42, "slip": {"table": [[0, 1], [0.01, 1.5]]}}},
     "contact.friction.slip.table: theta must be in [0, 1]"),
    ({"friction": {"coulomb": {"mu": 0.3, "mu_k": 0.2}}},
     "contact.friction.coulomb.mu_k: not with mu (give mu, or mu_s, mu_k and slip_length; "
     "not both)"),
    ({"friction": {"coulomb": {}}},
     "contact.friction.coulomb.mu: required (give mu, or mu_s, mu_k and slip_length)"),
    ({"friction": {"coulomb": {"mu_s": 0.3, "mu_k": 0.2}}},
     "contact.friction.coulomb.slip_length: required (give mu, or mu_s, mu_k and "
     "slip_length)"),
    ({"friction": {"coulomb": {"mu": -0.1}}},
     "contact.friction.coulomb.mu: must be >= 0 (a friction coefficient), got -0.1"),
    ({"friction": {"coulomb": {"mu_s": 0.2, "mu_k": 0.3, "slip_length": 1.0}}},
     "contact.friction.coulomb.mu_s: must be >= mu_k = 0.3 (the static coefficient is the "
     "larger), got 0.2"),
    ({"friction": {"coulomb": {"mu_s": 0.3, "mu_k": 0.2, "slip_length": 1.0},
                   "slip": {"theta_inf": 0.5, "s0": 1.0}}},
     "contact.friction.slip: not with coulomb mu_s, mu_k (the static/kinetic pair is the "
     "slip dependence; give one of them)"),
])
def test_refusals_name_the_key_and_the_allowed(contact, message):
    assert message in _refusal(**contact)


def test_an_unknown_kernel_is_refused_with_the_kernels():
    text = _refusal(memory={"b0": 1.0, "kernel": "bogus"})
    assert "contact.memory.kernel" in text
    assert all(name in text for name in ("exponential", "power", "table"))


@pytest.fixture
def toys(monkeypatch):
    """A toy law of each kind added to its registry (the normal law's key may be a field of
    x), and the schema's sections rebuilt from
    the registries as app/case/schema.py builds them (its memo of passed mappings off)."""
    kernel = ContactLawSpec(
        name="hyperbolic", formula="b0 / (1 + t/t_half)",
        keys={"t_half": ContactKey({**POSITIVE, "description": "the half time [s]"})},
        build=lambda c, b0: registry.memory_kernel("power", b0, alpha=1.0, tau=c["t_half"]),
        levels=lambda c: [7.0])
    slip = ContactLawSpec(
        name="halving", formula="1 / (1 + s/s_half)",
        keys={"s_half": ContactKey({**POSITIVE, "description": "the half slip [m s]"})},
        build=lambda c: SlipWeakening(0.0, c["s_half"]))
    bound = ContactLawSpec(
        name="flat", formula="tau = tau0", title="flat friction",
        keys={"tau0": ContactKey({**POSITIVE, "description": "the bound [N/m^2]"})},
        build=lambda c, param: PiecewiseLinearFriction(param("tau0", c["tau0"]), 0.0, 0.0,
                                                       1.0),
        levels=lambda c: [c["tau0"]])
    normal = ContactLawSpec(
        name="linear", formula="k r^+",
        keys={"k": ContactKey({"oneOf": [NONNEGATIVE, EXPRESSION], "description": "k"},
                              field="the toy stiffness")},
        build=lambda c, param, x: NormalCompliance(
            space_field(c["k"], x) if isinstance(c["k"], str) else param("k", c["k"])),
        levels=lambda c, r: [] if isinstance(c["k"], str) else [c["k"] * r])
    coulomb = ContactLawSpec(
        name="capped", formula="min(mu_c, 1) p_n", title="capped Coulomb (mu_c = {mu_c:g})",
        keys={"mu_c": ContactKey({**NONNEGATIVE, "description": "the coefficient"})},
        build=lambda c: CoulombLaw(min(c["mu_c"], 1.0)),
        check=lambda c, path, source: None)
    for reg, spec in ((KERNELS, kernel), (SLIPS, slip), (BOUNDS, bound), (NORMALS, normal),
                      (COULOMBS, coulomb)):
        monkeypatch.setitem(reg, spec.name, spec)
    for section, keys in (("memory", registry.kernel_keys()),
                          ("slip", registry.key_schemas(SLIPS)),
                          ("friction", registry.key_schemas(BOUNDS)),
                          ("normal_compliance", registry.key_schemas(NORMALS)),
                          ("coulomb", registry.key_schemas(COULOMBS))):
        for key, schema in keys.items():
            monkeypatch.setitem(SECTIONS[section], key, schema)
    monkeypatch.setattr(schemamemo, "passed", lambda key: False)
    monkeypatch.setattr(schemamemo, "remember", lambda key: None)


@pytest.mark.usefixtures("toys")
def test_a_new_law_is_one_spec():
    """Toy laws added to the registries: the schema takes their keys, the rules their
    required keys, the Case their tagged sections, the builders and the blow-up bound
    their factories and levels, the run log the bound's title."""
    assert SECTIONS["memory"]["kernel"]["enum"] == ["exponential", "power", "table",
                                                    "hyperbolic"]
    case = _case(memory={"b0": 2.0, "kernel": "hyperbolic", "t_half": 0.5},
                 friction={"tau0": 3.0, "slip": {"s_half": 0.02}})
    c = case.contact
    assert c.memory == Memory(2.0, "hyperbolic", {"t_half": 0.5}, "auto")
    assert c.friction == Friction("flat", {"tau0": 3.0}, Slip("halving", {"s_half": 0.02}))
    assert c.friction.b is None and c.friction.tau0 == 3.0
    assert section_kernel(c.memory) == PowerKernel(2.0, 1.0, 0.5)
    assert registry.slip_law(c.friction.slip) == SlipWeakening(0.0, 0.02)
    assert registry.contact_law(c, 1e-7).friction == PiecewiseLinearFriction(3.0, 0.0, 0.0,
                                                                             1.0)
    assert "flat friction" in case.active_terms()
    assert _law_levels(c, 1.0, 0.1) == pytest.approx([100.0 * 0.1, 7.0 * 0.1, 3.0],
                                                     rel=1e-15)
    linear = _case(normal_compliance={"k": "5 + 10 * x"}).contact
    assert linear.normal == Compliance("linear", {"k": "5 + 10 * x"}) and linear.c_nu is None
    law = registry.contact_law(linear, 1e-7, x=np.array([[0.0, 0.0], [0.5, 0.0]]))
    assert law.normal.c_nu.tolist() == [5.0, 10.0]
    assert varies_in_space(linear) and _law_levels(linear, 1.0, 0.1) == [1.0, 0.6, 0.6]
    assert _law_levels(_case(normal_compliance={"k": 40}).contact, 1.0, 0.1)[0] == 4.0
    capped = _case(friction={"coulomb": {"mu_c": 1.5}})
    fr = capped.contact.friction
    assert fr.coulomb == Coulomb("capped", {"mu_c": 1.5}) and fr.law is None
    assert (fr.coulomb.mu, fr.coulomb.mu_c, fr.coulomb.mu_k) == (1.0, 1.5, None)
    assert registry.coulomb_law(fr.coulomb) == CoulombLaw(1.0) and section_slip(fr) is None
    assert not fr.coulomb.has_slip
    assert "capped Coulomb (mu_c = 1.5)" in capped.active_terms()


@pytest.mark.usefixtures("toys")
def test_a_new_law_is_refused_by_the_same_rules():
    assert "contact.memory.t_half: required for the hyperbolic kernel" in \
        _refusal(memory={"b0": 2.0, "kernel": "hyperbolic"})
    assert ("contact.friction.tau0: not with b, c1, c2, u1 (give b, c1, c2, u1, or table, "
            "or tau0; only one)") in _refusal(friction={**LAW42, "tau0": 1.0})
    assert ("contact.friction.slip.s_half: not with theta_inf, s0 (give theta_inf, s0, or "
            "table, or s_half; only one)") in \
        _refusal(friction={**LAW42, "slip": {"theta_inf": 0.5, "s0": 1.0, "s_half": 1.0}})
    assert "contact.friction.tau0: not with law: python" in \
        _refusal(friction={"law": "python", "class": "F", "tau0": 1.0})
    assert "contact.friction.tau0: not with coulomb" in \
        _refusal(friction={"coulomb": {"mu": 0.3}, "tau0": 1.0})
    assert ("contact.friction.coulomb.mu_c: not with mu (give mu, or mu_s, mu_k and "
            "slip_length, or mu_c; only one)") in \
        _refusal(friction={"coulomb": {"mu": 0.3, "mu_c": 1.0}})
    assert "contact.friction.coulomb.mu_c: -1 is less than the minimum of 0" in \
        _refusal(friction={"coulomb": {"mu_c": -1}})
    assert ("contact.normal_compliance.k: not with c_nu (give c_nu, or table, or k; only "
            "one)") in _refusal(normal_compliance={"c_nu": 1.0, "k": 2.0})
    assert "contact.normal_compliance.k: " in _refusal(normal_compliance={"k": "5 + t"})
    assert "contact.normal_compliance.k" in _refusal(normal_compliance={"k": "1 - 10 * x"})


def test_two_laws_of_a_kind_may_not_declare_one_key(monkeypatch):
    clash = ContactLawSpec(name="clash", formula="", build=lambda c: None,
                           keys={"s0": ContactKey(POSITIVE)})
    monkeypatch.setitem(SLIPS, "clash", clash)
    with pytest.raises(ValueError, match="the key s0 is declared by two laws of one kind"):
        registry.key_schemas(SLIPS)


def test_a_field_coefficient_has_no_level_and_varies_in_space():
    c = _case(normal_compliance={"c_nu": "100 + 10 * x"}).contact
    assert varies_in_space(c) and not varies_in_space(_case().contact)
    assert _law_levels(c, 1.0, 0.1) == [1.0, 0.6, 0.6]
