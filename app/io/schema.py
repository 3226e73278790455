"""JSON schema of a case file (validated with jsonschema; defaults are filled from it).

Sections: physical data (mesh geometry, material, contact, loads, initial values, time) are
separate from numerical settings (solver), PETSc options (petsc, passed through with our
prefix) and output.  Every key has a description and, where sensible, a default; units SI.
Cross-key rules (dimension of vectors, time-grid combinations, ...) are checked in case.py.
"""
from __future__ import annotations

_num = {"type": "number"}
_pos = {"type": "number", "exclusiveMinimum": 0}
_nonneg = {"type": "number", "minimum": 0}
_expr = {"type": "string", "minLength": 1, "maxLength": 500}
_table = {"type": "array", "minItems": 1, "maxItems": 100000,
          "items": {"type": "array", "items": _num, "minItems": 2, "maxItems": 2}}
# a component of a load: a number, an expression in t, x, y, z, or a table in time
_component = {"oneOf": [_num, _expr, {"type": "object", "additionalProperties": False,
                                      "required": ["table"], "properties": {"table": _table}}]}
_vector = {"type": "array", "items": _component, "minItems": 2, "maxItems": 3,
           "description": "2 or 3 components (the mesh dimension): number, expression string "
                          "in t, x, y, z, or {table: [[t, value], ...]} (piecewise linear in t)"}


# a case name is one path component below results/: letters, digits, _ . -, not "." or ".."
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"


def _obj(props: dict, required: list | None = None, description: str = "",
         default=None) -> dict:
    out = {"type": "object", "additionalProperties": False, "properties": props,
           "description": description}
    if required:
        out["required"] = required
    if default is not None:
        out["default"] = default
    return out


SCHEMA = _obj({
    "name": {"type": "string", "pattern": NAME_PATTERN, "maxLength": 100,
             "description": "case name (default: the file name without extension); "
                            "names the default output directory results/<name>"},
    "description": {"type": "string", "description": "free text"},
    "mesh": _obj({
        "dim": {"enum": [2, 3], "default": 2,
                "description": "2: rectangle, plane stress (the paper); 3: box, isotropic Hooke"},
        "L1": {**_pos, "default": 1.0, "description": "length in x [m]"},
        "L2": {**_pos, "default": 1.0, "description": "length in y [m]"},
        "L3": {**_pos, "default": 1.0, "description": "length in z [m] (3D)"},
        "kind": {"enum": ["structured", "unstructured"], "default": "structured",
                 "description": "structured: transfinite n per side (2D: nested under "
                                "refinement); unstructured: gmsh Delaunay with target size h"},
        "n": {"type": "integer", "minimum": 1, "maximum": 4096, "default": 16,
              "description": "cells per side (structured)"},
        "h": {**_pos, "description": "target mesh size [m] (unstructured)"},
        "diagonal": {"enum": ["right", "left"], "default": "right",
                     "description": "2D structured: right = each square cut from (x0,y0) to "
                                    "(x1,y1), left = from (x0,y1) to (x1,y0)"},
    }, description="geometry: Gamma1 = {x = 0} (clamped), Gamma3 = bottom {y = 0} in 2D, "
                   "{z = 0} in 3D (contact), Gamma2 = the other sides (tractions)"),
    "material": _obj({
        "E": {**_pos, "description": "Young's modulus [N/m^2]"},
        "nu": {"type": "number", "minimum": 0, "exclusiveMaximum": 0.5,
               "description": "Poisson's ratio"},
        "viscoplastic": _obj({
            "lambda1": {**_pos, "description": "viscosity lambda1 of Gfun [N s/m^2]"},
            "lambda2": {**_pos, "description": "lambda2 of the kappa law Gk [s]"},
            "kappa0": {"oneOf": [_nonneg, _expr], "default": 0.0,
                       "description": "initial internal state variable kappa0 [N/m^2]: a "
                                      "number or an expression in x, y, z"},
        }, required=["lambda1", "lambda2"],
            description="Perzyna law (absent: elastic body, no history update)"),
    }, required=["E", "nu"], description="material"),
    "contact": _obj({
        "g": {**_pos, "description": "penetration bound: u_nu <= g on Gamma3 [m] "
                                     "(absent: no unilateral constraint)"},
        "normal_compliance": _obj({
            "c_nu": {**_nonneg, "description": "stiffness of p(r) = c_nu r^+ [N/m^3]"},
        }, required=["c_nu"], description="normal compliance (4.1)"),
        "memory": _obj({
            "b0": {**_nonneg, "description": "memory kernel amplitude b0 [N/(m^3 s)]"},
            "beta": {**_nonneg, "default": 0.0,
                     "description": "decay rate of the exponential kernel b0 exp(-beta t) [1/s]"},
            "kernel": {"enum": ["exponential", "power", "table"], "default": "exponential",
                       "description": "b(t) = b0 exp(-beta t), b0 (1 + t/tau)^-alpha, or b0 "
                                      "times the piecewise-linear table"},
            "alpha": {**_pos, "description": "exponent of the power kernel"},
            "tau": {**_pos, "description": "time scale of the power kernel [s]"},
            "table": {**_table, "description": "[[t, b], ...] of the table kernel"},
            "sum": {"enum": ["auto", "recursion", "direct"], "default": "auto",
                    "description": "auto: exact O(1) recursion for the exponential kernel, "
                                   "stored history and direct sum otherwise"},
        }, required=["b0"], description="memory term xi(t) = int_0^t b(t-s) u_nu^+(s) ds "
                                          "(absent: no memory term)"),
        "friction": _obj({
            "b": {**_nonneg, "description": "friction bound at zero slip [N/m^2]"},
            "c1": {**_nonneg, "description": "softening slope on 0 < |u_tau| < u1"},
            "c2": {**_nonneg, "description": "hardening slope on |u_tau| >= u1"},
            "u1": {**_pos, "description": "slip where softening turns into hardening [m]"},
            "slip": _obj({
                "theta_inf": {"type": "number", "minimum": 0, "maximum": 1,
                              "description": "limit of theta(s) for large accumulated slip"},
                "s0": {**_pos, "description": "slip scale of theta(s) [m s]"},
            }, required=["theta_inf", "s0"],
                description="slip dependence j = theta(s) psi, theta(s) = theta_inf + "
                            "(1 - theta_inf) exp(-s/s0), s = int_0^t |u_tau| (absent: none)"),
        }, required=["b", "c1", "c2", "u1"],
            description="nonmonotone friction law (4.2) (absent: frictionless)"),
    }, description="contact on Gamma3 (absent: Gamma3 is traction free)"),
    "loads": _obj({
        "f0": {**_vector, "description": "body force density [N/m^3]; " + _vector["description"]},
        "traction": _obj({
            side: {**_vector, "description": f"f2 on the {side} side [N/m^2]"}
            for side in ("right", "top", "bottom", "front", "back")
        }, description="tractions f2 per side: right {x = L1}, top {y = L2} (2D) / {z = L3} "
                       "(3D), front {y = 0} and back {y = L2} (3D), bottom only without contact"),
    }, description="loads"),
    "initial": _obj({
        "u0": {**_vector, "description": "initial displacement (must satisfy u_nu <= g and "
                                         "vanish on Gamma1)"},
        "sigma0": {"type": "array", "minItems": 2, "maxItems": 3,
                   "items": {"type": "array", "minItems": 2, "maxItems": 3, "items": _component},
                   "description": "initial stress, a symmetric d x d matrix of components"},
    }, description="initial values u0, sigma0 (default 0; kappa0 is in material.viscoplastic)"),
    "time": _obj({
        "T": {**_pos, "description": "final time [s]"},
        "N": {"type": "integer", "minimum": 1, "maximum": 1000000,
              "description": "number of time steps"},
        "k": {**_pos, "description": "uniform time step (instead of N) [s]"},
        "grading": {**_pos, "description": "geometric grading with N steps: k_{j+1} = grading "
                                           "k_j (instead of uniform steps)"},
        "times": {"type": "array", "items": _num, "minItems": 2, "maxItems": 1000001,
                  "description": "explicit time points 0 = t0 < t1 < ... (instead of T, N)"},
        "adaptive": _obj({
            "k_min": {**_pos, "description": "smallest step before the run gives up [s] "
                                             "(default: first step / 1024)"},
            "k_max": {**_pos, "description": "largest step [s] (default: T)"},
            "grow": {"type": "number", "minimum": 1, "default": 1.5,
                     "description": "factor by which the step grows after a fast step"},
            "fast_newton": {"type": "integer", "minimum": 1, "default": 4,
                            "description": "a step with at most this many Newton iterations "
                                           "is fast"},
            "max_indicator": {**_pos, "default": 1.0,
                              "description": "explicit scheme: halve the step while k r_max "
                                             "exceeds this (1: no overshoot, 2: limit)"},
        }, description="adaptive steps from the first step of the grid to T: a step is "
                       "rejected and halved when SNES fails or the stability indicator is "
                       "exceeded, and grows after fast Newton convergence (absent: fixed grid)"),
        "scheme": {"enum": ["explicit", "implicit"], "default": "explicit",
                   "description": "history terms at the left end point (explicit, the paper's "
                                  "(3.2)-(3.3)) or the right end point (implicit, backward "
                                  "Euler, stable for any k)"},
    }, description="time grid: T with N or k (uniform), T with N and grading, or times"),
    "solver": _obj({
        "method": {"enum": ["snes_vi", "fast", "auto"], "default": "auto",
                   "description": "step solver: snes_vi (PETSc SNES vinewtonrsls with bounds "
                                  "on the normal dofs of Gamma3, general), fast (one "
                                  "factorisation per run, Gamma3 condensation; explicit scheme "
                                  "and vertex quadrature), auto (fast where it applies and "
                                  "Gamma3 has at most 3000 dofs)"},
        "delta": {**_pos, "default": 1.0e-7,
                  "description": "regularisation width of |u_tau| (friction) and u_nu^+ "
                                 "(memory term) [m]"},
        "quadrature": {"enum": ["vertex", "gauss"], "default": "vertex",
                       "description": "Gamma3 quadrature: vertex (nodal) rule or Gauss"},
        "gauss_degree": {"type": "integer", "minimum": 1, "maximum": 10, "default": 2,
                         "description": "degree of the Gauss rule (quadrature: gauss)"},
    }, description="numerical settings of the step solver", default={}),
    "petsc": {"type": "object", "default": {},
              "additionalProperties": {"type": ["string", "number", "boolean", "null"]},
              "propertyNames": {"pattern": r"^[a-z][a-z0-9_]*$"},
              "description": "PETSc options without the leading '-', passed unchanged "
                             "with the prefix vpcontact_ (e.g. snes_rtol: 1e-10)"},
    "output": _obj({
        "every": {"type": "integer", "minimum": 1, "default": 1,
                  "description": "write the fields every m-th step (the last step always)"},
        "checkpoint_every": {"type": "integer", "minimum": 1,
                             "description": "save the full state (u, sigma, kappa, H_n, memory "
                                            "and slip histories, time position) every m-th "
                                            "step to checkpoint.npz, for run --restart DIR "
                                            "(absent: no checkpoints)"},
    }, description="outputs", default={}),
}, required=["mesh", "material", "loads", "time"])
SCHEMA["$schema"] = "http://json-schema.org/draft-07/schema#"

# PETSc options used unless the case or the command line says otherwise; the absolute
# tolerances snes_atol and snes_vi_zero_tolerance are for the paper's scales and are
# scaled to each case's size and loads (app/io/case.py, scaled_petsc_defaults).
DEFAULT_PETSC = {
    "snes_type": "vinewtonrsls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1.0e-10,
    "snes_atol": 1.0e-11,
    "snes_stol": 1.0e-14,
    "snes_vi_zero_tolerance": 1.0e-8,
    "snes_max_it": 50,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
