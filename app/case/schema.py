"""JSON schema of a case file (validated with jsonschema; defaults are filled from it).

Sections: physical data (mesh geometry, boundary parts, material, contact, loads, initial
values, time) are separate from numerical settings (solver), PETSc options (petsc, passed
through with our prefix) and output.  Every key has a description and, where sensible, a
default; units SI.  Cross-key rules (dimension of vectors, time-grid combinations, boundary
groups, keys that do not apply with mesh.file, ...) are checked in app/case/rules.py and
meshrules.py, which also fills the defaults that depend on other keys (boundaries).  The
PETSc defaults are the solvers' (app/solvers/options.py).
"""
from __future__ import annotations

from vpcontact.model.contactregistry import (
    BOUNDS,
    COULOMBS,
    NORMALS,
    SLIPS,
    kernel_keys,
    key_schemas,
    recursive_kernels,
)
from vpcontact.model.contactspec import EXPRESSION, NONNEGATIVE, NUMBER, POSITIVE, TABLE
from vpcontact.model.lawregistry import (
    LAWS,
    USER_LAW,
    kappa0_description,
    law_description,
)
from vpcontact.model.lawregistry import key_schemas as law_key_schemas

_num, _pos, _nonneg, _expr, _table = NUMBER, POSITIVE, NONNEGATIVE, EXPRESSION, TABLE
# a component of a load: a number, an expression in t, x, y, z, or a table in time
_component = {"oneOf": [_num, _expr, {"type": "object", "additionalProperties": False,
                                      "required": ["table"], "properties": {"table": _table}}]}
_vector = {"type": "array", "items": _component, "minItems": 2, "maxItems": 3,
           "description": "2 or 3 components (the mesh dimension): number, expression string "
                          "in t, x, y, z, or {table: [[t, value], ...]} (piecewise linear in t)"}
# a prescribed displacement component: a load component or null (that component is free)
_free_component = {"oneOf": [_num, _expr, {"type": "object", "additionalProperties": False,
                                           "required": ["table"],
                                           "properties": {"table": _table}},
                             {"type": "null"}]}
# a rigid cap's amplitude components (force, displacement: d; moment, rotation: 1 in 2D,
# 3 in 3D): a number, an expression in t, a table, or null (not given)
_cap_vector = {"type": "array", "items": _free_component, "minItems": 2, "maxItems": 3}
_cap_turn = {"oneOf": [_free_component, {"type": "array", "items": _free_component,
                                         "minItems": 3, "maxItems": 3}]}
_RIGID_CAP = {
    "type": "object", "additionalProperties": False,
    "properties": {
        "force": {**_cap_vector, "description": "the resultant force [N (3D), N/m (2D)] on "
                  "the cap, per component (null: not loaded)"},
        "moment": {**_cap_turn, "description": "the resultant moment about the reference "
                   "point (2D: one component, 3D: three; null: not loaded)"},
        "displacement": {**_cap_vector, "description": "the prescribed displacement [m] of "
                         "the reference point, per component (null: free)"},
        "rotation": {**_cap_turn, "description": "the prescribed (small) rotation [rad] (2D: "
                     "one component, 3D: three; null: free)"},
        "reference": {"type": "array", "items": _num, "minItems": 2, "maxItems": 3,
                      "description": "the reference point (absent: the group's centroid)"},
    }}

# a boundary part: a physical group's name (mesh.file) or tag (an integer >= 0), or a side of
# the built-in rectangle / box (left right bottom top, and front back in 3D)
_group = {"oneOf": [{"type": "string", "minLength": 1, "maxLength": 200},
                    {"type": "integer", "minimum": 0}]}
_groups = {"type": "array", "items": _group, "maxItems": 1000}


# a case name is one path component below results/: letters, digits, _ . -, not "." or ".."
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]*$"


# the constants of a law written by the user (law: python), viscoplastic or contact
_LAW_PARAMS = {"type": "object", "additionalProperties": {"type": "number"},
               "propertyNames": {"pattern": r"^[A-Za-z_][A-Za-z0-9_]*$"},
               "maxProperties": 100,
               "description": "law python: the keyword arguments of the class's constructor, "
                              "numbers in the units the law expects (absent: none)"}


def _python_law(part: str, what: str) -> dict:
    """The keys law, class, params of a contact law written by the user (``law: python``):
    part names the key in messages, what the function the class gives."""
    return {
        "law": {"enum": ["python"],
                "description": f"python: {what} is a law written by the user, the class "
                               "named by class in the module given with --law-module "
                               "FILE.py (a case file alone never runs code: without the "
                               f"option the case is refused); instead of the built-in "
                               f"law's keys of {part} (absent: the built-in law)"},
        "class": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_]*$", "maxLength": 100,
                  "description": "law python (required there): the name of the law's class "
                                 "in the module of --law-module FILE.py, built as "
                                 "Class(**params): a ScalarLaw (vpcontact.model.laws) or an "
                                 "object with energy(x), derivative(x), second_derivative(x) "
                                 "written with vpcontact.model.primitives.backend(x)"},
        "params": _LAW_PARAMS,
    }


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
        "file": {"type": "string", "minLength": 1, "maxLength": 4096,
                 "description": "a gmsh .msh (format 4.1 or 2.2, ASCII or binary) or .geo "
                                "file, relative to the case "
                                "file's directory; its physical groups name the boundary parts "
                                "(boundaries, loads); a .geo is meshed by gmsh at load time "
                                "(absent: the built-in rectangle / box of L1, L2, L3; the keys "
                                "L1 L2 L3 kind n h diagonal engine are not used with mesh.file)"},
        "dim": {"enum": [2, 3], "default": 2,
                "description": "2: plane body (material.plane), z = 0 for mesh.file; 3: solid "
                               "(a box, or a tetrahedral mesh.file), isotropic Hooke; with "
                               "mesh.file the file's dimension when absent (the default 2 is "
                               "the built-in mesh's), and refused if it contradicts the file"},
        "size": {**_pos, "default": 1.0,
                 "description": "factor on the characteristic lengths of a .geo mesh.file "
                                "(< 1: finer; only with a .geo)"},
        "L1": {**_pos, "default": 1.0, "description": "length in x [m] (built-in mesh)"},
        "L2": {**_pos, "default": 1.0, "description": "length in y [m] (built-in mesh)"},
        "L3": {**_pos, "default": 1.0, "description": "length in z [m] (built-in 3D mesh)"},
        "kind": {"enum": ["structured", "unstructured"], "default": "structured",
                 "description": "structured: transfinite n per side (2D: nested under "
                                "refinement); unstructured: gmsh Delaunay with target size h"},
        "n": {"type": "integer", "minimum": 1, "maximum": 4096, "default": 16,
              "description": "cells per side (structured)"},
        "h": {**_pos, "description": "target mesh size [m] (unstructured)"},
        "diagonal": {"enum": ["right", "left"], "default": "right",
                     "description": "2D structured: right = each square cut from (x0,y0) to "
                                    "(x1,y1), left = from (x0,y1) to (x1,y0)"},
        "engine": {"enum": ["gmsh", "dolfinx"], "default": "gmsh",
                   "description": "builder of the built-in structured rectangle / box (the "
                                  "same cells either way; unstructured meshes come from gmsh)"},
    }, description="the body: a gmsh mesh.file, or the built-in rectangle (0, L1) x (0, L2) / "
                   "box (0, L1) x (0, L2) x (0, L3) whose sides are the groups left {x = 0}, "
                   "right {x = L1}, bottom {y = 0} (3D: {z = 0}), top {y = L2} (3D: "
                   "{z = L3}) and in 3D front {y = 0}, back {y = L2}"),
    "boundaries": _obj({
        "clamped": {**_groups, "description": "the groups of Gamma1, where u = 0 (default: "
                                              "[left] for the built-in mesh, [] for mesh.file; "
                                              "[] is allowed when loads.displacement fixes "
                                              "the rigid motions)"},
        "contact": {**_groups, "description": "the groups of Gamma3, the contact boundary "
                                              "(default: [bottom] for the built-in mesh; "
                                              "required with mesh.file and a contact section)"},
    }, description="boundary parts: lists of group names (the built-in mesh's sides or "
                   "mesh.file's physical groups) or physical tags (integers >= 0, mesh.file "
                   "only); Gamma2 is the rest of the boundary.  Built-in meshes default to "
                   "clamped [left], contact [bottom]"),
    "material": _obj({
        "E": {"oneOf": [_pos, _expr],
              "description": "Young's modulus [N/m^2]: a number, or an expression in x, y, z "
                             "taken per cell (at its midpoint: E(x) in L-infinity, DG0); "
                             "with nu, the isotropic law; not with elasticity"},
        "nu": {"oneOf": [{"type": "number", "minimum": 0, "exclusiveMaximum": 0.5}, _expr],
               "description": "Poisson's ratio (dimensionless, 0 <= nu < 0.5): a number, or "
                              "an expression in x, y, z taken per cell (at its midpoint); "
                              "not with elasticity"},
        "elasticity": _obj({
            "orthotropic": _obj({
                "E": {"type": "array", "items": _pos, "minItems": 2, "maxItems": 3,
                      "description": "Young's moduli along the material axes [N/m^2]: [E1, "
                                     "E2, E3] (3D; 2D plane strain), [E1, E2] (2D plane "
                                     "stress)"},
                "nu": {"type": "array", "items": _num, "minItems": 1, "maxItems": 3,
                       "description": "Poisson's ratios nu_ij = -eps_j / eps_i under a "
                                      "uniaxial stress along a_i (dimensionless): [nu12, "
                                      "nu13, nu23], or [nu12] in 2D plane stress"},
                "G": {"type": "array", "items": _pos, "minItems": 1, "maxItems": 3,
                      "description": "shear moduli [N/m^2]: [G12, G13, G23], or [G12] in 2D "
                                     "plane stress"},
                "axes": {"type": "array", "minItems": 1, "maxItems": 2,
                         "items": {"type": "array", "items": _num, "minItems": 2,
                                   "maxItems": 3},
                         "description": "the material axes in the global frame (lengths do "
                                        "not matter; nonzero, orthogonal): [a1, a2] in 3D "
                                        "(a3 = a1 x a2), [a1] in 2D (a2 = a1 turned by +90 "
                                        "degrees)"},
            }, required=["E", "nu", "G", "axes"],
                description="orthotropic elasticity from engineering constants: in the "
                            "material axes the compliance has 1/E_i on the diagonal, -nu_ij "
                            "/ E_i off it, 1/G_ij on the shears; 2D plane stress takes its "
                            "in-plane block, plane strain (3D data) the reduced compliance "
                            "(eps_33 = 0)"),
            "voigt": {"type": "array", "minItems": 3, "maxItems": 6,
                      "items": {"type": "array", "items": _num, "minItems": 3, "maxItems": 6},
                      "description": "the stiffness matrix [N/m^2], symmetric positive "
                                     "definite, stresses from engineering strains (shears 2 "
                                     "eps_ij) in the order (11, 22, 12) in 2D (the in-plane "
                                     "law itself: material.plane does not change it), (11, "
                                     "22, 33, 23, 13, 12) in 3D"},
        }, description="an anisotropic elasticity E instead of E and nu: exactly one of "
                       "orthotropic and voigt; refused unless positive definite (check "
                       "prints m_E)"),
        "viscoplastic": _obj({      # the built-in laws' keys: app/model/lawregistry.py
            "kappa0": {"oneOf": [_nonneg, _expr], "default": 0.0,
                       "description": kappa0_description()},
            "law": {"enum": [*LAWS, USER_LAW],
                    "description": law_description(
                        "a law written by the user: the class named by class in the module "
                        "given with --law-module FILE.py")},
            **law_key_schemas(),
            "class": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_]*$",
                      "maxLength": 100,
                      "description": "law python (required there): the name of the law's "
                                     "class in the module of --law-module FILE.py (without "
                                     "the option the case is refused: a case file alone "
                                     "never runs code); built as Class(elasticity, "
                                     "**params)"},
            "params": _LAW_PARAMS,
        }, description="viscoplastic law: a built-in law (law; each declared in its module, "
                       "app/model/lawregistry.py) or a class written by the user (absent: "
                       "elastic body, no history update)"),
        "plane": {"enum": ["stress", "strain"], "default": "stress",
                  "description": "2D: plane stress (the paper's, a thin plate) or plane strain "
                                 "(a long body); not used in 3D"},
    }, description="material: E and nu (isotropic), or elasticity"),
    "contact": _obj({
        "g": {"oneOf": [_nonneg, _expr],
              "description": "the initial gap to the rigid foundation, the bound u_nu <= g on "
                             "Gamma3 [m]: a number >= 0 or an expression in x, y, z (not t), "
                             ">= 0 on Gamma3 (absent: no unilateral constraint)"},
        "direction": {"type": "array", "items": _num, "minItems": 2, "maxItems": 3,
                      "description": "[dx, dy(, dz)]: a fixed approach direction of a flat "
                                     "rigid foundation (normalised): u_nu = u . d, the "
                                     "tangential parts orthogonal to d; it must point from "
                                     "the body toward the obstacle, under 90 degrees to the "
                                     "outward normal at every Gamma3 node (refused otherwise, "
                                     "naming the node; warned of above 80 degrees on average) "
                                     "(absent: the outward "
                                     "unit normal of Gamma3 at each node; (0, -1) / (0, 0, -1) "
                                     "on the built-in bottom side).  With contact.pairs: "
                                     "every pair's normal, from its surface toward its "
                                     "target; each surface node is coupled to the target's "
                                     "point on the line through it along d (a ray cast) and "
                                     "the gap is measured along d, as linear (Hertz) theory "
                                     "does (absent: the target's normal at the closest "
                                     "point)"},
        "normal_compliance": _obj({      # the built-in laws' keys: contactregistry.py
            **key_schemas(NORMALS),
            **_python_law("contact.normal_compliance", "the normal compliance energy P(r) "
                          "(p = P' against the normal displacement r = u_nu [m], P'' its "
                          "slope)"),
        }, description="normal compliance p(r): c_nu r^+ (4.1), c_nu (r^+)^m, a table, or "
                       "a law written by the user (give c_nu, table or law: python)"),
        "memory": _obj({
            "b0": {"oneOf": [_nonneg, _expr],
                   "description": "memory kernel amplitude b0 [N/(m^3 s)]: a number >= 0 or "
                                  "an expression in x, y, z, >= 0 on Gamma3 (b(t, x) = "
                                  "b0(x) times the kernel's shape)"},
            **kernel_keys(),                # each kernel's keys: contactregistry.py
            "sum": {"enum": ["auto", "recursion", "direct"], "default": "auto",
                    "description": "auto: exact O(1) recursion for the "
                                   f"{' and '.join(recursive_kernels())} kernel, stored "
                                   "history and direct sum otherwise"},
        }, required=["b0"], description="memory term xi(t) = int_0^t b(t-s) u_nu^+(s) ds "
                                          "(absent: no memory term)"),
        "friction": _obj({
            **key_schemas(BOUNDS),          # the built-in bounds' keys: contactregistry.py
            "slip": _obj({
                **key_schemas(SLIPS),       # the slip laws' keys: contactregistry.py
            }, description="slip dependence j = theta(s) psi, theta(s) = theta_inf + "
                           "(1 - theta_inf) exp(-s/s0) or a table, s = int_0^t |u_tau| "
                           "(absent: none; give theta_inf and s0, or table)"),
            "coulomb": _obj({
                **key_schemas(COULOMBS),    # the Coulomb variants' keys: contactregistry.py
            }, description="Coulomb friction |sigma_tau| <= mu p_n (instead of b, c1, c2, u1 "
                           "or table): psi(rho) = mu p_n rho, regularised with solver.delta; "
                           "p_n by a fixed point in each step (needs normal_compliance or g); "
                           "give mu, or the static/kinetic pair mu_s, mu_k, slip_length: "
                           "mu(s) = mu_s - (mu_s - mu_k) min(s / slip_length, 1) (not with "
                           "slip)"),
            **_python_law("contact.friction", "the friction potential psi(rho) (the "
                          "friction stress psi' against the slip rho = |u_tau|_delta [m]; "
                          "an attribute m_j, the largest decreasing slope of psi', enters "
                          "(2.6), else m_j is not stated; slip still applies)"),
        }, description="nonmonotone friction law (4.2) of b, c1, c2, u1, a friction "
                       "table, or a law written by the user (absent: frictionless)"),
    }, description="contact on Gamma3 = boundaries.contact (built-in meshes: the bottom "
                   "side by default) with a rigid foundation (absent: Gamma3 is traction "
                   "free)"),
    "loads": _obj({
        "f0": {**_vector, "description": "body force density [N/m^3]; " + _vector["description"]},
        "traction": {"type": "object", "additionalProperties": _vector,
                     "description": "{group: [tx, ty(, tz)]}: traction f2 [N/m^2] on each "
                                    "group of Gamma2 (a name or a physical tag; the built-in "
                                    "mesh's sides left right bottom top, front back in 3D); "
                                    "not on a clamped group, nor on a contact group of a case "
                                    "with a contact section; components: number, expression "
                                    "in t, x, y, z, or {table: [[t, value], ...]}"},
        "pressure": {"type": "object", "additionalProperties": _component,
                     "description": "{group: p}: normal pressure [N/m^2] on each group of "
                                    "Gamma2, the traction -p n with the outward unit normal n "
                                    "of the reference configuration; p a number, expression "
                                    "in t, x, y, z, or {table: ...}"},
        "displacement": {"type": "object",
                         "additionalProperties": {"type": "array", "items": _free_component,
                                                  "minItems": 2, "maxItems": 3},
                         "description": "{group: [ux, uy(, uz)]}: prescribed displacement "
                                        "[m] on each group, a component being a number, "
                                        "expression in t, x, y, z, {table: ...} or null "
                                        "(free), at least one not null (e.g. a symmetry "
                                        "roller [0, null]); not on a clamped group, nor on a "
                                        "contact group of a case with a contact section"},
        "rigid": {"type": "object", "additionalProperties": _RIGID_CAP,
                  "description": "{group: {force, moment, displacement, rotation, "
                                 "reference}}: a rigid cap: the group moves rigidly, u = U + "
                                 "theta x (X - X_ref) (small rotations), each of its d(d+1)/2 "
                                 "amplitudes either loaded (force, moment: a resultant, "
                                 "default 0) or prescribed (displacement, rotation), never "
                                 "both; components a number, expression in t or {table: "
                                 "...}; not on a clamped, displaced or contact group"},
    }, description="loads"),
    "initial": _obj({
        "u0": {**_vector, "description": "initial displacement (must satisfy u_nu <= g on "
                                         "Gamma3 and vanish on Gamma1)"},
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
                                             "(default: first step / 1024; k_max must "
                                             "not be smaller)"},
            "k_max": {**_pos, "description": "largest step [s] (default: T)"},
            "grow": {"type": "number", "minimum": 1, "default": 1.5,
                     "description": "factor by which the step grows after a step that "
                                    "changed the solution by at most max_change"},
            "max_change": {"type": "number", "exclusiveMinimum": 0, "default": 0.2,
                           "description": "the step grows after one with max|u_n - u_{n-1}| "
                                          "<= max_change max|u_n| (a property of the "
                                          "solution: every step solver takes the same grid)"},
            "max_indicator": {**_pos, "default": 1.0,
                              "description": "explicit scheme: halve the step while k r_max "
                                             "exceeds this (1: no overshoot, 2: limit)"},
        }, description="adaptive steps from the first step of the grid to T: a step is "
                       "rejected and halved when the step solver fails or the stability "
                       "indicator is exceeded, and grows after a step that changed the "
                       "solution little (absent: fixed grid)"),
        "scheme": {"enum": ["explicit", "implicit"], "default": "explicit",
                   "description": "history terms at the left end point (explicit, the paper's "
                                  "(3.2)-(3.3)) or the right end point (implicit, backward "
                                  "Euler, stable for any k)"},
    }, description="time grid: T with N or k (uniform), T with N and grading, or times"),
    "solver": _obj({
        "method": {"enum": ["snes_vi", "condensed", "fast", "auto"], "default": "auto",
                   "description": "step solver: snes_vi (PETSc SNES vinewtonrsls with bounds "
                                  "on the normal dofs of Gamma3, general), condensed (one "
                                  "factorisation per run, Gamma3 condensation; explicit scheme "
                                  "and vertex quadrature; fast is its former name), auto "
                                  "(condensed where it applies and Gamma3 has at most 6000 "
                                  "dofs)"},
        "linear": {"enum": ["direct", "schur", "amg", "auto"], "default": "auto",
                   "description": "Newton systems of snes_vi: direct (LU of every Newton "
                                  "system), schur (one factorisation of the bulk stiffness "
                                  "per run and a dense Gamma3 Schur complement per Newton "
                                  "iteration; explicit scheme, one body without nodal "
                                  "frames, else direct; under mpirun on rank 0), amg (CG with "
                                  "algebraic multigrid, GAMG, knowing the rigid body modes; "
                                  "for large 3D meshes), auto (amg in 3D above 20000 dofs, "
                                  "else schur)"},
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
              "description": "PETSc options without the leading '-', passed with the "
                             "prefix vpcontact_ (e.g. snes_rtol: 1e-10); only those of the "
                             "allow-list in docs/user-guide.md (no python types, no files: "
                             "monitors and views to standard output only)"},
    "output": _obj({
        "every": {"type": "integer", "minimum": 1, "default": 1,
                  "description": "write the fields every m-th step (the last step always)"},
        "checkpoint_every": {"type": "integer", "minimum": 1,
                             "description": "save the full state (u, sigma, kappa, H_n, memory "
                                            "and slip histories, time position) every m-th "
                                            "step to checkpoint.npz, for run --restart DIR "
                                            "(absent: no checkpoints)"},
    }, description="outputs", default={}),
}, required=["mesh", "loads", "time"])
SCHEMA["$schema"] = "http://json-schema.org/draft-07/schema#"
# materials: the material section's own schema (the same dict) per physical group of cells,
# listed after material
_MATERIALS = {
    "type": "object", "minProperties": 1, "maxProperties": 1000,
    "additionalProperties": SCHEMA["properties"]["material"],
    "description": "with mesh.file, instead of material: one material per physical group of "
                   "cells of the body's dimension (its name, or its physical tag: an integer "
                   ">= 0), each with every key of material (its viscoplastic law included; "
                   "none: an elastic group); the groups must cover the body and have one "
                   "material.plane; either material or materials"}
# contact.pairs: two bodies of one mesh.file in contact; a pair's laws are the contact
# section's own schema (the same dicts): a law of the contact section serves every pair
# that does not give its own (app/case/pairrules.py)
_CONTACT = SCHEMA["properties"]["contact"]["properties"]
_CONTACT["pairs"] = {
    "type": "array", "minItems": 1, "maxItems": 100,
    "items": _obj({
        "surface": {**_group, "description": "the group of facets of one body whose nodes "
                                             "are projected (Gamma3 of the pair)"},
        "target": {**_group, "description": "the group of facets of the other body they "
                                            "are projected onto"},
        "g": {**_nonneg, "description": "an extra gap added to the measured initial "
                                        "distance: the bound u_nu <= d + g [m] (the thickness "
                                        "of a compliant interface layer; default 0: hard "
                                        "contact)"},
        "rule": {"enum": ["mortar", "node_to_segment"],
                 "description": "how a surface node's relative displacement is taken: "
                                "mortar (default: the phi_i-weighted mean of the jump over "
                                "the node's facets; passes the contact patch test) or "
                                "node_to_segment (at the node's point pi(x) of the target)"},
        **{key: _CONTACT[key] for key in ("normal_compliance", "memory", "friction")},
    }, required=["surface", "target"]),
    "description": "two deformable bodies of one mesh.file in contact (node to segment, "
                   "small sliding): each node of surface is coupled once to the point "
                   "pi(x) of target met along nu, the average of the surface's outward and "
                   "the target's inward normals; u_nu = (u(x) - u(pi(x))) . nu, the "
                   "initial distance d measured from the mesh; the laws act on "
                   "u_nu - d and the relative tangential displacement.  A pair's "
                   "normal_compliance, memory or friction replaces the contact section's "
                   "for that pair (which serves the pairs that give none); pairs with "
                   "different memory terms share the kernel (b0 may differ).  Not with g or "
                   "boundaries.contact (the pairs' surfaces are Gamma3); with direction, nu "
                   "is that direction and pi(x) the target's point along it"}
_KEYS = list(SCHEMA["properties"].items())
_AT = [key for key, _ in _KEYS].index("material") + 1
SCHEMA["properties"] = dict(_KEYS[:_AT] + [("materials", _MATERIALS)] + _KEYS[_AT:])
