"""Safe parsing of user expressions (priors, constraints, ``--prior EXPR``) into sympy.

User text is parsed with :mod:`ast` and translated node by node into sympy objects: only numbers,
the allowed signal names and parameters, ``+ - * / ** ^``, unary minus and a whitelist of
functions are accepted. Nothing is ever passed to ``eval``/``sympify`` of a string.
"""
from __future__ import annotations

import ast
import functools
import math
import re
import string
from collections.abc import Iterable, Mapping

import numpy as np
import sympy as sp
from sympy.printing.str import StrPrinter

from droneid.errors import ConfigError, DataError, MissingSignalError, did_you_mean

__all__ = ["parse_expression", "ALLOWED_FUNCTIONS", "compile_expression", "evaluate_expr", "symbol", "safe_format", "to_text", "c_code", "octave_code",
           "round_expr"]

#: Functions a user expression may call, by name.
ALLOWED_FUNCTIONS: Mapping[str, object] = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos,
    "atan": sp.atan, "atan2": sp.atan2, "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "exp": sp.exp, "log": sp.log, "sqrt": sp.sqrt, "abs": sp.Abs, "sign": sp.sign,
    "min": sp.Min, "max": sp.Max,
}
_CONSTANTS = {"pi": sp.pi, "e": sp.E}
_BINOPS = {
    ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b, ast.Pow: lambda a, b: a ** b,
}
_MAX_LEN = 2000
#: deepest nesting of operators and calls an expression may have (2 000 unary minus signs
#: would otherwise exhaust Python's recursion limit)
_MAX_DEPTH = 200
#: largest magnitude of a number literal (float64's range; a bigger integer is exact in sympy
#: and would only overflow later)
_MAX_LITERAL = 1e308
#: largest |exponent| when the base depends on a signal (a power of 10 000 is already far
#: beyond any physical model; SNGP's deepest cube chains stay below it)
_MAX_EXPONENT = 10_000
#: largest decimal exponent of a constant power a ** b (float64 ends at about 1e308): sympy
#: computes integer powers exactly, so 9**9**9 would run for hours without this bound
_MAX_LOG10 = 308.0
#: most arguments a function call may have (sympy's Min/Max compare them pairwise)
_MAX_ARGS = 8
_FLOAT_MAX_INT = int(np.finfo(np.float64).max)
_NON_FINITE = (sp.zoo, sp.oo, -sp.oo, sp.nan)


def symbol(name: str) -> sp.Symbol:
    """The sympy symbol droneid uses for a signal: real-valued, named as the signal."""
    return sp.Symbol(name, real=True)


#: binary operators whose left-leaning chains (``a + b - c + ...``) count as one nesting level
_CHAIN_OPS = (ast.Add, ast.Sub, ast.Mult, ast.Div)


def _chain(node) -> bool:
    return isinstance(node, ast.BinOp) and isinstance(node.op, _CHAIN_OPS)


def _depth(tree: ast.AST) -> int:
    """Nesting depth of ``tree``, computed without recursion (the tree may be very deep); a long
    sum or product ``a + b + c + ...`` is one level, as :func:`parse_expression` folds it in a loop."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, d = stack.pop()
        deepest = max(deepest, d)
        for child in ast.iter_child_nodes(node):
            flat = _chain(node) and child is node.left and _chain(child)
            stack.append((child, d if flat else d + 1))
    return deepest


def _constant_value(e: sp.Expr) -> complex | None:
    """The value of a constant expression as a Python complex (inf/nan when it does not fit
    float64), or None when ``e`` depends on a signal."""
    if e.free_symbols:
        return None
    try:
        return complex(sp.N(e, 17))
    except (TypeError, ValueError, OverflowError, ArithmeticError):
        return complex(float("nan"))


def parse_expression(text: str, signals: Iterable[str], params: Mapping[str, float] | None = None,
                     what: str = "expression") -> sp.Expr:
    """Parse ``text`` into a sympy expression over the symbols named in ``signals``.

    ``params`` are named numbers substituted as constants (e.g. ``{"g": 9.81, "k_D": 0.28}``).
    Raises :class:`ConfigError` naming ``what`` and the offending part for anything else,
    including expressions that are too long (over 2 000 characters) or too deeply nested
    (over 200 levels; a long sum or product counts as one), number literals beyond float64's range, powers whose exponent is larger
    than 10 000 or whose constant value would exceed 1e308, and any part that evaluates to a
    non-finite or non-real constant (``vx/0``, ``log(0)``, ``sqrt(-1)``, ``exp(1000)``).
    These bounds keep parsing fast: sympy would otherwise compute ``9**9**9`` exactly.
    """
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"{what}: empty expression")
    if len(text) > _MAX_LEN:
        raise ConfigError(f"{what}: expression longer than {_MAX_LEN} characters")
    signals = list(signals)
    params = dict(params or {})
    names = {n: symbol(n) for n in signals}
    try:
        # '^' means power (as in maths); Python would read it as xor with the wrong precedence
        source = text.strip().replace("^", "**")
        tree = ast.parse(source, mode="eval")
    except SyntaxError as exc:
        raise ConfigError(f"{what}: cannot parse {text!r}: {exc.msg}") from None
    except (ValueError, RecursionError, MemoryError) as exc:  # null bytes, absurd nesting
        raise ConfigError(f"{what}: cannot parse {text[:80]!r}: {type(exc).__name__}") from None
    if _depth(tree.body) > _MAX_DEPTH:
        raise ConfigError(f"{what}: {text[:40]!r}... is nested more than {_MAX_DEPTH} levels deep")

    def reject(node, problem):
        part = ast.get_source_segment(source, node) or ast.unparse(node)
        part = part if len(part) <= 60 else part[:57] + "..."
        raise ConfigError(f"{what}: '{part}' {problem} in {text!r}" if len(text) <= 200
                          else f"{what}: '{part}' {problem}")

    def power(node, base, exponent):
        ev = _constant_value(exponent)
        if ev is not None and ev.imag == 0 and math.isfinite(ev.real):
            bv = _constant_value(base)
            if bv is None:
                if abs(ev.real) > _MAX_EXPONENT:
                    reject(node, f"has an exponent beyond ±{_MAX_EXPONENT}")
            elif bv != 0 and abs(ev.real * math.log10(abs(bv))) > _MAX_LOG10:
                reject(node, "exceeds the float64 range (about 1e308)")
        return base ** exponent

    def checked(node, e):
        """``e`` with non-finite or non-real constants rejected."""
        if e.has(*_NON_FINITE):
            reject(node, "is infinite or undefined (division by zero, log(0), ...)")
        v = _constant_value(e)
        if v is not None and not (math.isfinite(v.real) and math.isfinite(v.imag)):
            reject(node, "evaluates to a number beyond the float64 range (about 1e308)")
        if v is not None and v.imag != 0:
            reject(node, "is not a real number")
        return e

    def conv(node):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            if not math.isfinite(node.value) or abs(node.value) > _MAX_LITERAL:
                reject(node, "is a number beyond the float64 range (about 1e308)")
            return sp.Float(node.value) if isinstance(node.value, float) else sp.Integer(node.value)
        if isinstance(node, ast.Name):
            if node.id in names:
                return names[node.id]
            if node.id in params:
                return checked(node, sp.Float(float(params[node.id])))
            if node.id in _CONSTANTS:
                return _CONSTANTS[node.id]
            raise ConfigError(
                f"{what}: unknown name '{node.id}' in {text!r}"
                f"{did_you_mean(node.id, [*names, *params, *_CONSTANTS])}; "
                f"signals available: {', '.join(signals) or 'none'}")
        if _chain(node):  # fold a + b - c * d ... along its left spine in a loop, not recursion
            spine = []
            while _chain(node):
                spine.append(node)
                node = node.left
            acc = conv(node)
            for link in reversed(spine):
                acc = checked(link, _BINOPS[type(link.op)](acc, conv(link.right)))
            return acc
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return checked(node, power(node, conv(node.left), conv(node.right)))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = conv(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in ALLOWED_FUNCTIONS:
                fname = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
                raise ConfigError(
                    f"{what}: function '{fname}' is not allowed in {text!r}"
                    f"{did_you_mean(fname, ALLOWED_FUNCTIONS)}; allowed: {', '.join(ALLOWED_FUNCTIONS)}")
            if node.keywords:
                raise ConfigError(f"{what}: keyword arguments are not allowed in {text!r}")
            if not node.args:
                reject(node, "has no arguments")
            if len(node.args) > _MAX_ARGS:
                reject(node, f"has more than {_MAX_ARGS} arguments")
            func = ALLOWED_FUNCTIONS[node.func.id]
            args = [conv(a) for a in node.args]
            # sympy flattens max(max(a, b), c) and compares all arguments pairwise
            if sum(len(a.args) if a.func == func else 1 for a in args) > _MAX_ARGS:
                reject(node, f"has more than {_MAX_ARGS} arguments once nested calls are merged")
            return checked(node, func(*args))
        raise ConfigError(f"{what}: '{ast.unparse(node)}' is not allowed in {text!r} "
                          "(only numbers, signal names, + - * / ** and whitelisted functions)")

    try:
        expr = conv(tree.body)
    except ConfigError:
        raise
    except TypeError as exc:  # wrong number of function arguments
        raise ConfigError(f"{what}: {exc} in {text!r}") from None
    except (RecursionError, MemoryError, ArithmeticError, ValueError) as exc:  # sympy's limits
        raise ConfigError(f"{what}: cannot build {text[:80]!r}: {type(exc).__name__}") from None
    return sp.sympify(expr)


def _short(expr, limit: int = 80) -> str:
    """``str(expr)`` cut to ``limit`` characters; never raises (huge integers refuse ``str``)."""
    try:
        text = str(expr)
    except (ValueError, RecursionError):
        return f"<{type(expr).__name__}>"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def compile_expression(expr: sp.Expr, names: Iterable[str]):
    """A numpy function ``f(columns: Mapping[str, ndarray]) -> ndarray`` evaluating ``expr``.

    The function broadcasts constants to the length of the columns and never raises on
    overflow or domain errors (those become inf/nan, which callers check; a complex result
    becomes nan). Anything that cannot be compiled raises :class:`ConfigError`, a column the
    expression needs and ``columns`` lacks :class:`MissingSignalError`, a column that is not
    numeric :class:`DataError`.
    """
    if not isinstance(expr, sp.Basic):
        raise ConfigError(f"compile_expression needs a sympy expression, got {type(expr).__name__} "
                          "(parse text with parse_expression first)")
    return _compiled(expr, tuple(names))


@functools.lru_cache(maxsize=4096)
def _compiled(expr: sp.Expr, names: tuple[str, ...]):
    """:func:`compile_expression` once per (expression, names): the ladder and the guards
    evaluate the same terms hundreds of times, and sympy's code generation costs ~2 ms each."""
    names = list(names)
    syms = [symbol(n) for n in names]
    try:
        # numpy has no complex infinity; integers beyond 2**53 would reach numpy as Python ints
        # too large for float64 (OverflowError): give both as the floats they evaluate to
        repl = {sp.zoo: sp.nan}
        repl.update({i: sp.Float(float(i)) if abs(int(i)) < _FLOAT_MAX_INT else sp.oo * sp.sign(i)
                     for i in expr.atoms(sp.Integer) if abs(int(i)) > 2 ** 53})
        expr = expr.xreplace(repl)
        fn = sp.lambdify(syms, expr, modules="numpy")
    except Exception as exc:  # noqa: BLE001 - sympy's printers raise anything (KeyError, ...)
        raise ConfigError(f"cannot compile expression {_short(expr)}: {type(exc).__name__}") from None
    used = {s.name for s in expr.free_symbols}
    missing = sorted(used - set(names))
    if missing:
        raise MissingSignalError(missing[0], names, where=f"expression {_short(expr)}")

    def evaluate(columns: Mapping[str, np.ndarray]) -> np.ndarray:
        absent = [nm for nm in names if nm in used and nm not in columns]
        if absent:
            raise MissingSignalError(absent[0], list(columns), where=f"expression {_short(expr)}")
        try:
            cols = {nm: np.asarray(columns[nm], dtype=float) for nm in names if nm in used}
        except (TypeError, ValueError) as exc:
            raise DataError(f"expression {_short(expr)}: a column is not numeric ({exc})") from None
        first = next(iter(cols.values())) if cols else \
            np.atleast_1d(next(iter(columns.values()))) if columns else np.zeros(1)
        n = first.shape[0] if first.ndim else 1
        args = [cols[nm] if nm in cols else np.zeros(n) for nm in names]
        with np.errstate(all="ignore"):
            try:
                out = np.asarray(fn(*args))
            except ArithmeticError:  # e.g. a Python-int power overflowing float64
                out = np.full(n, np.nan)
            if np.iscomplexobj(out):
                out = np.where(out.imag == 0, out.real, np.nan)
            out = out.astype(float, copy=False)
        return np.broadcast_to(out, (n,)).copy() if out.ndim == 0 or out.size == 1 else out

    return evaluate


#: widest field and most digits a format spec may ask for in :func:`safe_format`
_MAX_FORMAT_WIDTH, _MAX_FORMAT_PRECISION, _MAX_TEMPLATE_LEN = 40, 17, 2000
_FORMAT_SPEC = re.compile(r"^(?P<align>[<>^=]?)(?P<sign>[+\- ]?)0?(?P<width>\d*)"
                          r"(?:\.(?P<precision>\d+))?[eEfFgG%]?$")


def evaluate_expr(expr: sp.Expr, columns: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    """``expr`` on data columns, broadcast to ``n`` rows (constants too); invalid values stay nan."""
    names = sorted(s.name for s in expr.free_symbols)
    if not names:
        return np.full(n, float(expr))
    with np.errstate(all="ignore"):
        v = compile_expression(expr, names)({k: np.asarray(columns[k], float) for k in names})
    return np.broadcast_to(np.asarray(v, float), (n,)).astype(float)


def safe_format(template: str, values: Mapping[str, object], what: str = "format string") -> str:
    """``template.format(**values)`` for user-written templates, without its dangers.

    Only ``{name}`` and ``{name:SPEC}`` fields are allowed, where ``name`` is a key of ``values``
    and SPEC a numeric spec such as ``.3g``, ``>8.2f`` or ``+.1%`` with a width of at most 40 and
    a precision of at most 17 (``{k:>2000000000}`` would allocate gigabytes). Attribute and
    index access (``{k.__class__}``, ``{k[0]}``), positional fields, ``!r`` conversions and
    nested fields raise :class:`ConfigError` naming ``what``. ``{{`` and ``}}`` are literal braces.
    """
    if not isinstance(template, str):
        raise ConfigError(f"{what}: must be a string, got {type(template).__name__}")
    if len(template) > _MAX_TEMPLATE_LEN:
        raise ConfigError(f"{what}: longer than {_MAX_TEMPLATE_LEN} characters")
    try:
        parsed = list(string.Formatter().parse(template))
    except ValueError as exc:
        raise ConfigError(f"{what}: bad format string {template!r}: {exc}") from None
    out = []
    for literal, name, spec, conversion in parsed:
        out.append(literal)
        if name is None:
            continue
        field_text = "{" + name + (f"!{conversion}" if conversion else "") + (f":{spec}" if spec else "") + "}"
        if not name:
            raise ConfigError(f"{what}: field {field_text} needs a name, e.g. {{k:.3g}}")
        if not name.isidentifier():
            kind = "attribute or index access" if ("." in name or "[" in name) else "a name"
            raise ConfigError(f"{what}: field {field_text} is not allowed: only {{name}} or "
                              f"{{name:.3g}}, no {kind}" if kind != "a name" else
                              f"{what}: field {field_text} needs a name, e.g. {{k:.3g}}")
        if conversion:
            raise ConfigError(f"{what}: field {field_text}: conversion !{conversion} is not allowed")
        if name not in values:
            raise ConfigError(f"{what}: field {field_text} uses unknown name '{name}'"
                              f"{did_you_mean(name, values)}; names: {', '.join(sorted(values))}")
        m = _FORMAT_SPEC.match(spec or "")
        if m is None:
            raise ConfigError(f"{what}: field {field_text}: format spec {spec!r} is not allowed "
                              "(use e.g. .3g, .2f, >8.2f)")
        if m["width"] and int(m["width"]) > _MAX_FORMAT_WIDTH:
            raise ConfigError(f"{what}: field {field_text}: width {int(m['width'])} is over "
                              f"{_MAX_FORMAT_WIDTH}")
        if m["precision"] and int(m["precision"]) > _MAX_FORMAT_PRECISION:
            raise ConfigError(f"{what}: field {field_text}: precision {int(m['precision'])} is over "
                              f"{_MAX_FORMAT_PRECISION}")
        value = values[name]
        if spec and isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
            value = float(value)
        try:
            out.append(format(value, spec or ""))
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{what}: field {field_text} cannot format {value!r}: {exc}") from None
    return "".join(out)


# -- writing expressions back ------------------------------------------------------------------
class _Printer(StrPrinter):
    """sympy's str printer, spelled the way :func:`parse_expression` reads it back."""

    def _print_Abs(self, expr):
        return f"abs({self._print(expr.args[0])})"

    def _print_Exp1(self, expr):
        return "e"

    def _print_Float(self, expr):
        return repr(float(expr))


def _shortest_float_printer(base):
    """A sympy code printer class that writes every float as its shortest round-trip repr
    (``9.81``, never ``9.8100000000000005``): the same double, digits a person can read."""
    class _Shortest(base):
        def _print_Float(self, expr):
            return repr(float(expr))
    return _Shortest


def c_code(expr: sp.Expr) -> str:
    """``expr`` as a C99 expression, floats shortest round-trip (:func:`repr`)."""
    from sympy.printing.c import C99CodePrinter
    return _shortest_float_printer(C99CodePrinter)().doprint(expr)


def octave_code(expr: sp.Expr) -> str:
    """``expr`` as a MATLAB/Octave expression, floats shortest round-trip (:func:`repr`)."""
    from sympy.printing.octave import OctaveCodePrinter
    return _shortest_float_printer(OctaveCodePrinter)().doprint(expr)


def to_text(expr: sp.Expr) -> str:
    """``expr`` as text the safe parser (:func:`parse_expression`) reads back, floats in full."""
    return _Printer({"full_prec": True}).doprint(expr)


def round_expr(expr: sp.Expr, digits: int = 4) -> sp.Expr:
    """Every float in ``expr`` rounded to ``digits`` significant figures (for display)."""
    reps = {}
    for f in expr.atoms(sp.Float):
        v = float(f)
        reps[f] = sp.Float(float(f"{v:.{digits}g}")) if v != 0 else sp.Integer(0)
    return expr.xreplace(reps)
