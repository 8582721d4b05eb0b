"""Generate ``firmware/core/kin_gen.[ch]``: the fields and brackets as C, from sympy.

The C core evaluates the Lie brackets from these exact expressions (sympy
differentiates; common subexpressions are shared), never by finite differences.
The generated files are committed; ``tests/test_kin_codegen.py`` checks that running
this again reproduces them. Regenerate after changing ``symbolic/models.py``::

    python -m snakebot.symbolic.codegen          # rewrite the files
    python -m snakebot.symbolic.codegen --check  # exit 1 if they are out of date
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import sympy as sp
from sympy.printing.c import C99CodePrinter

from snakebot.paths import REPO_ROOT
from snakebot.symbolic.models import SymbolicModel, snake3, trident

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


def _c_function(name: str, model: SymbolicModel, names: tuple[str, ...]) -> tuple[str, str]:
    """(prototype, definition) of a function writing the named fields of model at q."""
    n = len(model.q)
    exprs = [c for f in names for c in model.fields[f]]
    params = model.params
    if model.name == "trident" and model.form == "body":
        exprs, extra = _trig_of_corners(model, exprs)
        params = (*params, *extra)
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), optimizations="basic")
    printer = _Printer()
    if model.name == "snake3":
        signature = f"void {name}(double l, const double *q, double *out)"
        bound = {params[0]: None}
    else:
        signature = (
            f"void {name}(double r, double l, const double *alpha, const double *q, double *out)"
        )
        bound = {params[0]: None, params[1]: None}
    used = set().union(*(e.free_symbols for _, e in temps), *(e.free_symbols for e in reduced))
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
    for sym, expr in temps:
        lines.append(f"    const double {sym} = {printer.doprint(expr)};")
    for k, expr in enumerate(reduced):
        field, comp = divmod(k, n)
        lines.append(f"    out[{k}] = {printer.doprint(expr)};  /* {names[field]}[{comp}] */")
    lines.append("}")
    return signature + ";", "\n".join(lines)


def _functions() -> list[tuple[str, str, str]]:
    """(doc comment, prototype, definition) for every generated function."""
    out = []
    s3 = snake3()
    for suffix, names in (("g", s3.inputs), ("all", tuple(s3.fields))):
        doc = (
            f"3-link snake, half-link l, q = (x, y, theta, phi1, phi2): writes "
            f"{', '.join(names)} (5 components each) to out."
        )
        out.append((doc, *_c_function(f"kin_gen_snake3_{suffix}", s3, names)))
    for form in ("body", "world"):
        tri = trident(form)
        for suffix, names in (("g", tri.inputs), ("all", tuple(tri.fields))):
            corners = (
                "alpha = (alpha1..3, cos alpha1..3, sin alpha1..3)"
                if form == "body"
                else "alpha = (alpha1..3)"
            )
            doc = (
                f"Trident, {form}-velocity inputs, q = (x, y, theta, phi1..3), {corners}: "
                f"writes {', '.join(names)} (6 components each) to out."
            )
            out.append((doc, *_c_function(f"kin_gen_trident_{form}_{suffix}", tri, names)))
    return out


BANNER = f"""/* GENERATED by host/snakebot/symbolic/codegen.py from the sympy models in
 * host/snakebot/symbolic/models.py: do not edit; regenerate with
 * `python -m snakebot.symbolic.codegen`. sympy {sp.__version__}.
 * Fields are written field after field: out[f * n + k] is component k of field f. */
"""


def generate() -> dict[str, str]:
    """The text of the generated header and source, by file name."""
    functions = _functions()
    header = [BANNER, "#ifndef SNAKEBOT_KIN_GEN_H", "#define SNAKEBOT_KIN_GEN_H", ""]
    for doc, proto, _ in functions:
        header += [f"/* {doc} */", proto, ""]
    header += ["#endif", ""]
    source = [BANNER, "#include <math.h>", "", f'#include "{HEADER_NAME}"', ""]
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
            print(f"{CORE_DIR / name} is out of date: run python -m snakebot.symbolic.codegen")
        return 1 if stale else 0
    for name, text in generate().items():
        (CORE_DIR / name).write_text(text)
        print(f"wrote {CORE_DIR / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
