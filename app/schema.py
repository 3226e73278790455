"""JSON schema of a case file (validated with jsonschema; defaults are filled from it).

Sections: physical data (mesh geometry, material, contact, loads, time) are separate from
numerical settings (solver), PETSc options (petsc, passed through with our prefix) and
output.  Every key has a description and, where sensible, a default; units are SI.
"""
from __future__ import annotations

_num = {"type": "number"}
_pos = {"type": "number", "exclusiveMinimum": 0}
_nonneg = {"type": "number", "minimum": 0}
_vec2 = {"type": "array", "items": _num, "minItems": 2, "maxItems": 2}


def _obj(props: dict, required: list | None = None, description: str = "") -> dict:
    out = {"type": "object", "additionalProperties": False, "properties": props,
           "description": description}
    if required:
        out["required"] = required
    return out


SCHEMA = _obj({
    "name": {"type": "string", "pattern": r"^[A-Za-z0-9_.-]+$",
             "description": "case name (default: the file name without extension); "
                            "names the default output directory results/<name>"},
    "description": {"type": "string", "description": "free text"},
    "mesh": _obj({
        "L1": {**_pos, "default": 1.0, "description": "length of the body in x [m]"},
        "L2": {**_pos, "default": 1.0, "description": "height of the body in y [m]"},
        "kind": {"enum": ["structured", "unstructured"], "default": "structured",
                 "description": "structured: transfinite n x n, nested under refinement; "
                                "unstructured: gmsh Delaunay with target size h"},
        "n": {"type": "integer", "minimum": 1, "maximum": 4096, "default": 16,
              "description": "cells per side (structured)"},
        "h": {**_pos, "description": "target mesh size [m] (unstructured)"},
        "diagonal": {"enum": ["right", "left"], "default": "right",
                     "description": "structured: right = each square cut from (x0,y0) to "
                                    "(x1,y1), left = from (x0,y1) to (x1,y0)"},
    }, description="geometry Omega = (0,L1)x(0,L2): Gamma1 = left side (clamped), "
                   "Gamma2 = right and top sides (tractions), Gamma3 = bottom (contact)"),
    "material": _obj({
        "E": {**_pos, "description": "Young's modulus [N/m^2]"},
        "nu": {"type": "number", "minimum": 0, "exclusiveMaximum": 0.5,
               "description": "Poisson's ratio (plane stress)"},
        "viscoplastic": _obj({
            "lambda1": {**_pos, "description": "viscosity lambda1 of Gfun [N s/m^2]"},
            "lambda2": {**_pos, "description": "lambda2 of the kappa law Gk [s]"},
            "kappa0": {**_nonneg, "default": 0.0,
                       "description": "initial internal state variable kappa0 [N/m^2]"},
        }, required=["lambda1", "lambda2"],
            description="Perzyna law (absent: elastic body, no history update)"),
    }, required=["E", "nu"], description="plane-stress material"),
    "contact": _obj({
        "g": {**_pos, "description": "penetration bound: u_nu <= g on Gamma3 [m] "
                                     "(absent: no unilateral constraint)"},
        "normal_compliance": _obj({
            "c_nu": {**_nonneg, "description": "stiffness of p(r) = c_nu r^+ [N/m^3]"},
        }, required=["c_nu"], description="normal compliance (4.1)"),
        "friction": _obj({
            "b": {**_nonneg, "description": "friction bound at zero slip [N/m^2]"},
            "c1": {**_nonneg, "description": "softening slope on 0 < |u_tau| < u1"},
            "c2": {**_nonneg, "description": "hardening slope on |u_tau| >= u1"},
            "u1": {**_pos, "description": "slip where softening turns into hardening [m]"},
        }, required=["b", "c1", "c2", "u1"],
            description="nonmonotone friction law (4.2) (absent: frictionless)"),
    }, description="contact on Gamma3 (absent: Gamma3 is traction free)"),
    "loads": _obj({
        "f0": {**_vec2, "default": [0.0, 0.0], "description": "body force density [N/m^3]"},
        "traction": _obj({
            "right": {**_vec2, "description": "f2 on {x = L1} [N/m^2]"},
            "top": {**_vec2, "description": "f2 on {y = L2} [N/m^2]"},
            "bottom": {**_vec2, "description": "traction on {y = 0}; only without contact"},
        }, description="tractions f2 per boundary part"),
    }, description="loads, constant in time"),
    "time": _obj({
        "T": {**_pos, "description": "final time [s]"},
        "N": {"type": "integer", "minimum": 1, "maximum": 1000000,
              "description": "number of uniform time steps (k = T/N)"},
    }, required=["T", "N"], description="time grid 0 = t0 < ... < tN = T"),
    "solver": {"default": {}, **_obj({
        "method": {"enum": ["snes_vi"], "default": "snes_vi",
                   "description": "step solver: PETSc SNES vinewtonrsls with bounds on the "
                                  "normal dofs of Gamma3"},
        "delta": {**_pos, "default": 1.0e-7,
                  "description": "regularisation width of |xi| in the friction term [m]"},
        "quadrature": {"enum": ["vertex", "gauss"], "default": "vertex",
                       "description": "Gamma3 quadrature: vertex (nodal) rule or Gauss"},
        "gauss_degree": {"type": "integer", "minimum": 1, "maximum": 10, "default": 2,
                         "description": "degree of the Gauss rule (quadrature: gauss)"},
    }, description="numerical settings of the step solver")},
    "petsc": {"type": "object", "default": {},
              "additionalProperties": {"type": ["string", "number", "boolean", "null"]},
              "propertyNames": {"pattern": r"^[a-z][a-z0-9_]*$"},
              "description": "PETSc options without the leading '-', passed unchanged "
                             "with the prefix vpcontact_ (e.g. snes_rtol: 1e-10)"},
    "output": {"default": {}, **_obj({
        "every": {"type": "integer", "minimum": 1, "default": 1,
                  "description": "write the fields every m-th step (the last step always)"},
    }, description="outputs")},
}, required=["mesh", "material", "loads", "time"])
SCHEMA["$schema"] = "http://json-schema.org/draft-07/schema#"

# PETSc options used unless the case or the command line says otherwise.
DEFAULT_PETSC = {
    "snes_type": "vinewtonrsls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1.0e-10,
    "snes_atol": 1.0e-11,
    "snes_stol": 1.0e-14,
    "snes_max_it": 50,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
