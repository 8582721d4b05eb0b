"""Generate ``firmware/core/kin_gen.[ch]``: the fields and brackets as C, from sympy.

The C core evaluates the Lie brackets from these exact expressions (sympy
differentiates; common subexpressions are shared), never by finite differences.
The generated files are committed; ``tests/model/test_kin_codegen.py`` checks that running
this again reproduces them. Regenerate after changing ``model/symbolic/models.py``::

    python -m snakebot.model.symbolic.codegen          # rewrite the files
    python -m snakebot.model.symbolic.codegen --check  # exit 1 if they are out of date
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import sympy as sp
from sympy.printing.c import C99CodePrinter

from snakebot.model.symbolic.models import SymbolicModel, snake3, trident
from snakebot.paths import REPO_ROOT

CORE_DIR = REPO_ROOT / "firmware" / "core"
HEADER_NAME = "kin_gen.h"
SOURCE_NAME = "kin_gen.c"


class _Printer(C99CodePrinter):
    """C99 printer that writes small integer powers as products (faster than pow())."""

    def _print_Pow(self, expr: sp.Pow) -> str:
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 1 <= abs(int(exp)) <= 6:
            factor = self.parenthesize(base, 100)
            product = "*".join([factor] * abs(int(exp)))
            return product if exp > 0 else f"1.0/({product})"
        return super()._print_Pow(expr)


def _trig_of_corners(
    model: SymbolicModel, exprs: list[sp.Expr]
) -> tuple[list[sp.Expr], tuple[sp.Symbol, ...]]:
    """Body-form trident: rewrite cos(phi_i) as cos(nu_i) cos(alpha_i) + sin(nu_i) sin(alpha_i)
    (nu_i = alpha_i + phi_i, whose sine and cosine are needed anyway) with the corner
    angles' cosines and sines as inputs: three fewer libm calls per evaluation."""
    phis, alphas = model.q[3:], model.params[2:]
    cos_a = sp.symbols("cos_alpha1:4", real=True)
    sin_a = sp.symbols("sin_alpha1:4", real=True)
    rewrite = {
        sp.cos(p): sp.cos(a + p) * ca + sp.sin(a + p) * sa
        for p, a, ca, sa in zip(phis, alphas, cos_a, sin_a, strict=True)
    }
    return [e.subs(rewrite) for e in exprs], (*cos_a, *sin_a)


def _batched_trig(
    exprs: list[sp.Expr], sincos: str = "kin_sincos"
) -> tuple[list[sp.Expr], list[str], set[sp.Symbol]]:
    """Replace every sin(a) and cos(a) by an entry of the arrays ``sn`` and ``cs`` that one
    call of ``sincos`` (``kin_sincos``'s signature) fills for all the angles a at once (the
    core evaluates a block of angles in the time libm takes for about two). Also returns
    the C lines of that call and the symbols the angles use."""
    angles = sorted(
        {f.args[0] for e in exprs for f in e.atoms(sp.sin, sp.cos)}, key=sp.default_sort_key
    )
    if not angles:
        return exprs, [], set()
    table: dict[sp.Expr, sp.Symbol] = {}
    for j, a in enumerate(angles):
        table[sp.sin(a)] = sp.Symbol(f"sn[{j}]", real=True)
        table[sp.cos(a)] = sp.Symbol(f"cs[{j}]", real=True)
    printer = _Printer()
    values = ", ".join(printer.doprint(a) for a in angles)
    size = f"KIN_TRIG_PADDED({len(angles)})"
    lines = [
        f"    const double angle[{size}] = {{{values}}};",
        f"    double sn[{size}], cs[{size}];",
        f"    {sincos}({len(angles)}, angle, sn, cs);",
    ]
    return [e.xreplace(table) for e in exprs], lines, set().union(*(a.free_symbols for a in angles))


def _collected(exprs: list[sp.Expr]) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Symbol]]:
    """Each expression that is a polynomial in the ``sn``/``cs`` entries, as the sum of
    its monomials in them, each coefficient a symbol ``w<k>`` of its own: the coefficients
    depend on the inputs and constants alone, so they are computed while the sines are,
    and a velocity takes one multiply per trig term and the additions after them (not a
    chain of operations on each sine). Returns the expressions, the coefficients'
    expressions and their symbols; others (a quotient of them) are left as they are."""
    trig = sorted(
        {s for e in exprs for s in e.free_symbols if s.name.startswith(("sn[", "cs["))},
        key=sp.default_sort_key,
    )
    out: list[sp.Expr] = []
    coefs: list[sp.Expr] = []
    names: list[sp.Symbol] = []
    for e in exprs:
        try:
            poly = sp.Poly(sp.expand(e), *trig) if trig else None
        except sp.PolynomialError:
            poly = None
        if poly is None:
            out.append(e)
            continue
        terms = []
        for powers, coef in poly.terms():
            monomial = sp.Mul(*(t**k for t, k in zip(trig, powers, strict=True)))
            coef = sp.factor(coef)
            if coef.is_Number or monomial == 1 or coef.is_Symbol or (-coef).is_Symbol:
                terms.append(coef * monomial)
            elif coef in coefs:
                terms.append(names[coefs.index(coef)] * monomial)
            else:
                names.append(sp.Symbol(f"w{len(names)}", real=True))
                coefs.append(coef)
                terms.append(names[-1] * monomial)
        out.append(sp.Add(*terms))
    return out, coefs, names


def _c_function(
    name: str, model: SymbolicModel, names: tuple[str, ...], velocity: bool = False
) -> tuple[str, str]:
    """(what the header holds, definition) of a function writing the named fields of model
    at q, or with ``velocity`` their combination sum_i u[i] field_i (one vector, no field
    stored). The header holds a prototype; for a velocity, the whole of ``<name>_by``, an
    inline function taking the sine routine as its first argument, and the definition is
    that function called with ``kin_sincos``: an integrator's step compiled for a wider
    instruction set then inlines the velocity with sines it can inline there too."""
    n = len(model.q)
    if velocity:
        inputs = [sp.Symbol(f"u[{i}]", real=True) for i in range(len(names))]
        exprs = [
            sum((u * model.fields[f][k] for u, f in zip(inputs, names, strict=True)), sp.S.Zero)
            for k in range(n)
        ]
    else:
        exprs = [c for f in names for c in model.fields[f]]
    params = model.params
    if model.name == "trident" and model.form == "body":
        exprs, extra = _trig_of_corners(model, exprs)
        params = (*params, *extra)
    if model.name == "snake3":
        # sines and cosines of the angle sums from those of the joint angles (the
        # addition theorem): three angles to evaluate instead of five
        exprs = [sp.expand_trig(e) for e in exprs]
    sincos = "sincos" if velocity else "kin_sincos"
    exprs, trig_lines, angle_symbols = _batched_trig(exprs, sincos)
    coefs: list[sp.Expr] = []
    weights: list[sp.Symbol] = []
    if velocity:
        exprs, coefs, weights = _collected(exprs)
    temps, reduced = sp.cse(coefs + exprs, symbols=sp.numbered_symbols("t"), optimizations="basic")
    weight_values, reduced = reduced[: len(coefs)], reduced[len(coefs) :]
    printer = _Printer()
    out_args = "const double *u, double *out" if velocity else "double *out"
    if model.name == "snake3":
        args, call = f"double l, const double *q, {out_args}", "l, q, u, out"
        bound = {params[0]: None}
    else:
        args = f"double r, double l, const double *alpha, const double *q, {out_args}"
        call = "r, l, alpha, q, u, out"
        bound = {params[0]: None, params[1]: None}
    signature = f"void {name}({args})"
    if velocity:
        wrapper = f"{signature}\n{{\n    {name}_by(kin_sincos, {call});\n}}"
        signature = f"static inline void {name}_by(kin_sincos_fn sincos, {args})"
    used = set().union(
        *(e.free_symbols for _, e in temps), *(e.free_symbols for e in (*weight_values, *reduced))
    )
    used |= angle_symbols
    lines = [signature, "{"]
    for i, s in enumerate(model.q):
        if s in used:
            lines.append(f"    const double {s} = q[{i}];")
    for i, s in enumerate(params):
        if s not in bound and s in used:
            lines.append(f"    const double {s} = alpha[{i - len(bound)}];")
    unused = [str(s) for s in params if s in bound and s not in used]
    for s in unused:
        lines.append(f"    (void){s};")
    lines += trig_lines
    for sym, expr in (*temps, *zip(weights, weight_values, strict=True)):
        lines.append(f"    const double {sym} = {printer.doprint(expr)};")
    for k, expr in enumerate(reduced):
        field, comp = divmod(k, n)
        what = f"qdot[{comp}]" if velocity else f"{names[field]}[{comp}]"
        lines.append(f"    out[{k}] = {printer.doprint(expr)};  /* {what} */")
    lines.append("}")
    if velocity:
        return "\n".join(lines), wrapper
    return signature + ";", "\n".join(lines)


def _functions() -> list[tuple[str, str, str]]:
    """(doc comment, prototype, definition) for every generated function."""
    out = []
    s3 = snake3()
    doc = (
        "3-link snake, half-link l, q = (x, y, theta, phi1, phi2): writes the velocity "
        "qdot = u[0] g1 + u[1] g2 (5 components) to out."
    )
    out.append((doc, *_c_function("kin_gen_snake3_v", s3, s3.inputs, velocity=True)))
    names = tuple(s3.fields)
    doc = (
        f"3-link snake, half-link l, q = (x, y, theta, phi1, phi2): writes "
        f"{', '.join(names)} (5 components each) to out."
    )
    out.append((doc, *_c_function("kin_gen_snake3_all", s3, names)))
    for form in ("body", "world"):
        tri = trident(form)
        corners = (
            "alpha = (alpha1..3, cos alpha1..3, sin alpha1..3)"
            if form == "body"
            else "alpha = (alpha1..3)"
        )
        where = f"Trident, {form}-velocity inputs, q = (x, y, theta, phi1..3), {corners}"
        doc = f"{where}: writes the velocity qdot = u[0] g1 + u[1] g2 + u[2] g3 to out."
        out.append((doc, *_c_function(f"kin_gen_trident_{form}_v", tri, tri.inputs, velocity=True)))
        names = tuple(tri.fields)
        doc = f"{where}: writes {', '.join(names)} (6 components each) to out."
        out.append((doc, *_c_function(f"kin_gen_trident_{form}_all", tri, names)))
    return out


BANNER = f"""/* GENERATED by host/snakebot/model/symbolic/codegen.py from the sympy models in
 * host/snakebot/model/symbolic/models.py: do not edit; regenerate with
 * `python -m snakebot.model.symbolic.codegen`. sympy {sp.__version__}.
 * Fields are written field after field: out[f * n + k] is component k of field f. */
"""


def generate() -> dict[str, str]:
    """The text of the generated header and source, by file name."""
    functions = _functions()
    header = [BANNER, "#ifndef SNAKEBOT_KIN_GEN_H", "#define SNAKEBOT_KIN_GEN_H", ""]
    header += ['#include "kin_trig.h"', ""]
    for doc, proto, body in functions:
        if proto.startswith("static inline"):  # a velocity: the inline body, then its own
            header += [f"/* {doc} The sines by `sincos`. */", proto, ""]
            header += [f"/* {doc} */", body.split("\n", 1)[0] + ";", ""]
        else:
            header += [f"/* {doc} */", proto, ""]
    header += ["#endif", ""]
    source = [
        BANNER,
        "#include <math.h>",
        "",
        f'#include "{HEADER_NAME}"',
        '#include "kin_trig.h"',
        "",
    ]
    for _, _, body in functions:
        source += [body, ""]
    return {HEADER_NAME: "\n".join(header), SOURCE_NAME: "\n".join(source)}


def stale_files(directory: Path = CORE_DIR) -> list[str]:
    """Names of generated files that differ from what generate() gives now."""
    return [
        name
        for name, text in generate().items()
        if not (directory / name).is_file() or (directory / name).read_text() != text
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="only check, exit 1 if stale")
    args = parser.parse_args(argv)
    if args.check:
        stale = stale_files()
        for name in stale:
            print(
                f"{CORE_DIR / name} is out of date: run python -m snakebot.model.symbolic.codegen"
            )
        return 1 if stale else 0
    for name, text in generate().items():
        (CORE_DIR / name).write_text(text)
        print(f"wrote {CORE_DIR / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
