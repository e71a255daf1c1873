#!/usr/bin/python3
"""Find a small elimination template for an action-matrix minimal solver.

Offline tool (numpy only: `apt-get install python3-numpy`, run with
/usr/bin/python3). It follows the classic construction of Kukelova, Bujnak and
Pajdla, "Automatic generator of minimal problem solvers" (ECCV 2008): multiply
the equations of a random instance by monomials, find the standard monomials
(basis B) of the quotient ring by Gaussian elimination in a graded reverse
lexicographic order, then greedily drop rows that are not needed to reduce
a*B (a = the action variable) to B. The printout is the template used by the
C++ solver: which equation is multiplied by which monomial, the column order
(eliminated | reducible | basis) and the action matrix layout.

Problems are Python functions returning random polynomials as
{exponent tuple: coefficient}. Usage:
    /usr/bin/python3 tools/elimination_template.py three_quadrics
"""
import itertools
import sys

import numpy as np


def monomials_up_to(nvars, degree):
    out = []
    for d in range(degree + 1):
        for e in itertools.product(range(d + 1), repeat=nvars):
            if sum(e) == d:
                out.append(e)
    return out


def grevlex_key(e):
    # Larger key = larger monomial: total degree, then reverse lexicographic.
    return (sum(e), tuple(-x for x in reversed(e)))


def multiply(p, m):
    return {tuple(a + b for a, b in zip(e, m)): c for e, c in p.items()}


def rref_pivots(mat, tol=1e-9):
    """Row echelon form with row pivoting; returns (matrix, pivot columns)."""
    a = mat.copy()
    rows, cols = a.shape
    pivots = []
    r = 0
    for c in range(cols):
        if r == rows:
            break
        p = r + np.argmax(np.abs(a[r:, c]))
        if abs(a[p, c]) < tol * max(1.0, np.abs(a).max()):
            continue
        a[[r, p]] = a[[p, r]]
        a[r] /= a[r, c]
        for k in range(rows):
            if k != r and a[k, c] != 0:
                a[k] -= a[k, c] * a[r]
        pivots.append(c)
        r += 1
    return a, pivots


def build(polys, multipliers):
    rows = [(i, m) for i, ms in enumerate(multipliers) for m in ms]
    mons = sorted({e for i, m in rows for e in multiply(polys[i], m)},
                  key=grevlex_key, reverse=True)
    index = {e: k for k, e in enumerate(mons)}
    mat = np.zeros((len(rows), len(mons)))
    for r, (i, m) in enumerate(rows):
        for e, c in multiply(polys[i], m).items():
            mat[r, index[e]] = c
    return rows, mons, mat


def reduces(rows, mons, mat, basis, reducible):
    """True when every monomial of `reducible` is a combination of `basis`
    modulo the row space of `mat` restricted to `rows` (indices)."""
    others = [m for m in mons if m not in basis and m not in reducible]
    order = others + list(reducible) + list(basis)
    idx = {m: k for k, m in enumerate(mons)}
    sub = mat[np.ix_(rows, [idx[m] for m in order])]
    _, pivots = rref_pivots(sub)
    need = set(range(len(others), len(others) + len(reducible)))
    return need <= set(pivots)


def find_template(polys, multipliers, action_var, nvars):
    rows, mons, mat = build(polys, multipliers)
    _, pivots = rref_pivots(mat)
    standard = [mons[c] for c in range(len(mons)) if c not in pivots]
    maxdeg = max(sum(m) for m in mons)
    basis = [m for m in standard if sum(m) < maxdeg]
    unit = tuple(1 if k == action_var else 0 for k in range(nvars))
    products = [tuple(a + b for a, b in zip(m, unit)) for m in basis]
    reducible = [m for m in products if m not in basis]
    keep = list(range(len(rows)))
    assert reduces(keep, mons, mat, basis, reducible), "template too small"
    # Greedy pruning, largest multipliers first.
    for r in sorted(keep, key=lambda r: grevlex_key(rows[r][1]), reverse=True):
        trial = [k for k in keep if k != r]
        if reduces(trial, mons, mat, basis, reducible):
            keep = trial
    used = sorted({e for r in keep for e in multiply(polys[rows[r][0]], rows[r][1])},
                  key=grevlex_key, reverse=True)
    return [rows[r] for r in keep], used, basis, reducible, products


def three_quadrics(rng):
    mons = monomials_up_to(3, 2)
    return [{m: rng.standard_normal() for m in mons} for _ in range(3)], 3


PROBLEMS = {"three_quadrics": (three_quadrics, 2, 0),
            "three_quadrics_z": (three_quadrics, 2, 2)}


def main():
    name = sys.argv[1] if len(sys.argv) > 1 else "three_quadrics"
    make, mult_degree, action_var = PROBLEMS[name]
    rng = np.random.default_rng(1)
    polys, nvars = make(rng)
    multipliers = [monomials_up_to(nvars, mult_degree) for _ in polys]
    rows, used, basis, reducible, products = find_template(
        polys, multipliers, action_var, nvars)
    print(f"{name}: {len(rows)} rows x {len(used)} monomials, "
          f"basis {len(basis)}, reducible {len(reducible)}")
    print("rows (equation, multiplier):", rows)
    print("basis:", basis)
    print("action products:", products)
    print("reducible:", reducible)
    print("monomials:", used)


if __name__ == "__main__":
    main()
