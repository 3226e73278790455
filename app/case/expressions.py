"""A small, safe expression language for loads and initial values in case files.

An expression is a string in t (time) and x, y, z (coordinates) with numbers, + - * / **,
unary minus, parentheses, the constants pi and e, and the functions sin, cos, tan, exp, log,
sqrt, abs, tanh, min, max.  It is parsed with Python's ``ast`` into a tree whose every node
is checked against this whitelist and then translated into UFL (or evaluated with numpy);
no case-file text ever reaches ``eval`` or ``exec``.
"""
from __future__ import annotations

import ast
import math
import operator
import sys

import numpy as np

MAX_LENGTH = 500
MAX_DEPTH = 40
NAMES = ("t", "x", "y", "z")
CONSTANTS = {"pi": math.pi, "e": math.e}
FUNCTIONS = ("sin", "cos", "tan", "exp", "log", "sqrt", "abs", "tanh", "min", "max")
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_NUMPY = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
          "sqrt": np.sqrt, "abs": np.abs, "tanh": np.tanh, "min": np.minimum,
          "max": np.maximum}


class ExpressionError(ValueError):
    """An expression that is not in the language, with the reason."""


def parse(text: str, allowed_names=NAMES) -> ast.Expression:
    """Parse and check an expression.

    Args:
        text: the expression.
        allowed_names: the variable names it may use.

    Returns:
        The checked tree.

    Raises:
        ExpressionError: with the reason, if the text is not an allowed expression.
    """
    if not isinstance(text, str) or not text.strip():
        raise ExpressionError("empty expression")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"not an expression: {exc.msg}") from None
    _check(tree.body, set(allowed_names), 0)
    return tree


def _check(node, names: set, depth: int) -> None:
    if depth > MAX_DEPTH:
        raise ExpressionError("expression nested too deeply")
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise ExpressionError(f"only numbers are allowed as constants, got {node.value!r}")
        try:
            finite = math.isfinite(float(node.value))
        except OverflowError:           # an integer literal beyond the largest float
            raise ExpressionError(f"number out of range: an integer of "
                                  f"{len(str(node.value))} digits (allowed: magnitudes up to "
                                  f"{sys.float_info.max:.3g})") from None
        if not finite:
            raise ExpressionError(f"number out of range: {node.value!r} (allowed: magnitudes "
                                  f"up to {sys.float_info.max:.3g})")
    elif isinstance(node, ast.Name):
        if node.id not in names and node.id not in CONSTANTS:
            raise ExpressionError(f"unknown name '{node.id}' (allowed: "
                                  f"{', '.join(sorted(names) + sorted(CONSTANTS))})")
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BINOPS:
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.left, names, depth + 1)
        _check(node.right, names, depth + 1)
    elif isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, (ast.USub, ast.UAdd)):
            raise ExpressionError(f"operator {type(node.op).__name__} is not allowed")
        _check(node.operand, names, depth + 1)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise ExpressionError(f"function not allowed (allowed: {', '.join(FUNCTIONS)})")
        if node.keywords or not node.args:
            raise ExpressionError(f"{node.func.id}(): positional arguments only")
        expected = 2 if node.func.id in ("min", "max") else 1
        if len(node.args) != expected:
            raise ExpressionError(f"{node.func.id}() takes {expected} argument(s)")
        for arg in node.args:
            _check(arg, names, depth + 1)
    else:
        raise ExpressionError(f"{type(node).__name__} is not allowed in an expression")


def _translate(node, symbols: dict, lib: dict):
    if isinstance(node, ast.Expression):
        return _translate(node.body, symbols, lib)
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return symbols[node.id] if node.id in symbols else CONSTANTS[node.id]
    if isinstance(node, ast.BinOp):
        left, right = _translate(node.left, symbols, lib), _translate(node.right, symbols, lib)
        try:
            return _BINOPS[type(node.op)](left, right)
        except (OverflowError, ZeroDivisionError) as exc:
            raise ExpressionError(f"arithmetic error: {exc}") from None
    if isinstance(node, ast.UnaryOp):
        v = _translate(node.operand, symbols, lib)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.Call):
        return lib[node.func.id](*(_translate(a, symbols, lib) for a in node.args))
    raise ExpressionError(type(node).__name__)  # unreachable after _check


def to_ufl(tree: ast.Expression, symbols: dict):
    """The UFL expression of a checked tree.

    Args:
        tree: a tree from ``parse``.
        symbols: t, x, y, z -> UFL objects.

    Returns:
        The UFL expression.
    """
    import ufl
    lib = {"sin": ufl.sin, "cos": ufl.cos, "tan": ufl.tan, "exp": ufl.exp, "log": ufl.ln,
           "sqrt": ufl.sqrt, "abs": abs, "tanh": ufl.tanh, "min": ufl.min_value,
           "max": ufl.max_value}
    return _translate(tree, symbols, lib)


def names(tree: ast.Expression) -> set[str]:
    """The variable names an expression uses.

    Args:
        tree: a tree from ``parse``.

    Returns:
        The names among t, x, y, z.
    """
    return {n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and n.id not in CONSTANTS}


def evaluate(tree: ast.Expression, symbols: dict) -> np.ndarray:
    """Values of a checked tree, without warnings.

    Invalid operations give NaN or inf, and a result that is not real (a negative number to a
    fractional power) gives NaN.

    Args:
        tree: a tree from ``parse``.
        symbols: t, x, y, z -> numpy arrays (that broadcast) or floats.

    Returns:
        The values (float array).

    Raises:
        ExpressionError: for a Python-level arithmetic error in constants (e.g. 1/0).
    """
    with np.errstate(all="ignore"):
        value = np.asarray(_translate(tree, symbols, _NUMPY))
    if np.iscomplexobj(value):
        value = np.where(value.imag == 0, value.real, np.nan)
    return value.astype(float)
