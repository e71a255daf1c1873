#!/usr/bin/python3
"""Elimination template for the 6-point ray-to-line pose problems p6L / m-p6L.

Offline tool (numpy only: `apt-get install python3-numpy`, run with
/usr/bin/python3). It writes src/linecloud/solvers/p6l_template.h, the table the
C++ solver (solvers/p6l.cc) is built from.

The problem (Speciale et al., CVPR 2019, p6L / m-p6L; the generalized relative
pose problem of Stewénius, Nistér, Oskarsson, Åström, "Solutions to minimal
generalized relative pose problems", OMNIVIS 2005): find R, t with
    d_iᵀ (R w_i + t × R v_i) + m_iᵀ R v_i = 0,   i = 1..6,
for query rays (d_i, m_i) (m_i = 0 for one camera) and map lines (v_i, w_i).
With the Cayley form R̃ = (1 − |s|²) I + 2[s]× + 2ssᵀ = (1 + |s|²) R, each
equation is aᵢ(s)ᵀ t̃ + bᵢ(s) = 0 with aᵢ = R̃vᵢ × dᵢ, bᵢ = dᵢᵀR̃wᵢ + mᵢᵀR̃vᵢ
quadratic in s = (x, y, z). (t̃, 1) spans the null space of the 6 × 4 matrix
[aᵢᵀ bᵢ], so its fifteen 4 × 4 minors vanish. Each minor (degree 8) is
(1 + |s|²) times a sextic; the factor carries a spurious surface of solutions
and is divided out. The 15 sextics have exactly 64 common solutions (checked
here over a prime field: the quotient ring has dimension 64, Hilbert function
1, 3, 6, 10, 15, 21, 7, 1).

Construction (Kukelova, Bujnak, Pajdla, "Automatic generator of minimal
problem solvers", ECCV 2008), all arithmetic exact modulo a prime so that no
rank decision depends on a tolerance:
  1. multiply every sextic by every monomial of degree ≤ 2 (150 rows, 165
     monomials of degree ≤ 8) and row-reduce in grevlex order; the monomials
     without a pivot are the standard monomials B (64);
  2. the action of x maps B to B ∪ R, R = x·B \\ B (26 monomials);
  3. drop rows greedily (largest multiplier first) while every monomial of R
     still reduces to a combination of B alone.
The result is a 99 × 163 template: 73 eliminated monomials, 26 reducible, 64
basis monomials. It is checked on further random instances, with and without
the m_i (one camera vs. a rig).

Usage: /usr/bin/python3 tools/p6l_template.py [--out FILE] [--checks N]
"""
import argparse
import itertools
import random

import numpy as np

import elimination_template
from elimination_template import grevlex_key

PRIME = 2147483647  # 2^31 - 1: products of two residues fit in int64


def monomials_up_to(degree):
    return elimination_template.monomials_up_to(3, degree)


# Polynomials in (x, y, z) over GF(PRIME): {exponent triple: residue}.
def p_add(a, b, sign=1):
    out = dict(a)
    for e, c in b.items():
        out[e] = (out.get(e, 0) + sign * c) % PRIME
    return {e: c for e, c in out.items() if c}


def p_mul(a, b):
    out = {}
    for e1, c1 in a.items():
        for e2, c2 in b.items():
            e = (e1[0] + e2[0], e1[1] + e2[1], e1[2] + e2[2])
            out[e] = (out.get(e, 0) + c1 * c2) % PRIME
    return {e: c for e, c in out.items() if c}


def p_scale(a, k):
    return {e: (c * k) % PRIME for e, c in a.items() if (c * k) % PRIME}


def p_shift(a, m):
    return {(e[0] + m[0], e[1] + m[1], e[2] + m[2]): c for e, c in a.items()}


def divide_by_norm(a):
    """Exact quotient of a by x² + y² + z² + 1 (long division in x)."""
    divisor = {(2, 0, 0): 1, (0, 2, 0): 1, (0, 0, 2): 1, (0, 0, 0): 1}
    a = dict(a)
    quotient = {}
    while a:
        e = max(a)
        if e[0] < 2:
            raise ValueError("minor not divisible by 1 + |s|^2")
        term = {(e[0] - 2, e[1], e[2]): a[e]}
        quotient = p_add(quotient, term)
        a = p_add(a, p_mul(term, divisor), -1)
    return quotient


def det(m):
    if len(m) == 1:
        return m[0][0]
    out = {}
    for j in range(len(m)):
        sub = [row[:j] + row[j + 1:] for row in m[1:]]
        out = p_add(out, p_mul(m[0][j], det(sub)), 1 if j % 2 == 0 else -1)
    return out


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def cayley_times(u):
    """R̃ u = (1 − |s|²) u + 2 s × u + 2 s (s·u), as three quadrics."""
    out = []
    for i in range(3):
        p = {(0, 0, 0): u[i] % PRIME}
        for k in range(3):
            e = [0, 0, 0]
            e[k] = 2
            p = p_add(p, {tuple(e): -u[i]})
        out.append(p)
    unit = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    for k in range(3):  # 2 s × u: the coefficient of s_k is 2 e_k × u
        e_k = [1 if j == k else 0 for j in range(3)]
        c = cross(e_k, u)
        for i in range(3):
            out[i] = p_add(out[i], {unit[k]: 2 * c[i]})
    for j in range(3):  # 2 s_i s_j u_j
        for i in range(3):
            e = [0, 0, 0]
            e[i] += 1
            e[j] += 1
            out[i] = p_add(out[i], {tuple(e): 2 * u[j]})
    return out


def random_sextics(rng, central):
    def vec():
        return [rng.randint(-1000, 1000) for _ in range(3)]
    rows = []
    for _ in range(6):
        point, v, d, origin = vec(), vec(), vec(), vec()
        w = cross(point, v)
        m = [0, 0, 0] if central else cross(origin, d)
        rv, rw = cayley_times(v), cayley_times(w)
        a = [p_add(p_scale(rv[1], d[2]), p_scale(rv[2], d[1]), -1),
             p_add(p_scale(rv[2], d[0]), p_scale(rv[0], d[2]), -1),
             p_add(p_scale(rv[0], d[1]), p_scale(rv[1], d[0]), -1)]
        b = {}
        for k in range(3):
            b = p_add(b, p_add(p_scale(rw[k], d[k]), p_scale(rv[k], m[k])))
        rows.append(a + [b])
    return [divide_by_norm(det([rows[i] for i in subset]))
            for subset in itertools.combinations(range(6), 4)]


def row_reduce(a):
    """Reduced row echelon form over GF(PRIME); returns (matrix, pivot columns)."""
    a = a.copy() % PRIME
    rows, cols = a.shape
    pivots = []
    r = 0
    for c in range(cols):
        if r == rows:
            break
        nonzero = np.nonzero(a[r:, c])[0]
        if len(nonzero) == 0:
            continue
        p = r + nonzero[0]
        a[[r, p]] = a[[p, r]]
        a[r] = (a[r] * pow(int(a[r, c]), PRIME - 2, PRIME)) % PRIME
        column = a[:, c].copy()
        column[r] = 0
        hit = np.nonzero(column)[0]
        if len(hit):
            a[hit] = (a[hit] - (column[hit, None] * a[r][None, :]) % PRIME) % PRIME
        pivots.append(c)
        r += 1
    return a, pivots


def build(sextics, rows):
    mons = sorted({e for i, m in rows for e in p_shift(sextics[i], m)},
                  key=grevlex_key, reverse=True)
    index = {e: k for k, e in enumerate(mons)}
    mat = np.zeros((len(rows), len(mons)), dtype=np.int64)
    for r, (i, m) in enumerate(rows):
        for e, c in p_shift(sextics[i], m).items():
            mat[r, index[e]] = c
    return mons, index, mat


def reduces(mat, index, mons, basis, reducible, keep):
    """Every reducible monomial is a combination of basis monomials alone,
    modulo the span of the rows `keep`."""
    basis_set, red_set = set(basis), set(reducible)
    others = [m for m in mons if m not in basis_set and m not in red_set]
    order = others + list(reducible) + list(basis)
    sub = mat[np.ix_(keep, [index[m] for m in order])]
    reduced, pivots = row_reduce(sub)
    pivot_set = set(pivots)
    need = set(range(len(others), len(others) + len(reducible)))
    if not need <= pivot_set:
        return False
    free_others = [c for c in range(len(others)) if c not in pivot_set]
    for r, c in enumerate(pivots):
        if c in need and free_others and np.any(reduced[r, free_others]):
            return False
    return True


def action_sets(basis):
    basis_set = set(basis)
    products = [(b[0] + 1, b[1], b[2]) for b in basis]
    return products, [p for p in products if p not in basis_set]


def find_template(seed):
    sextics = random_sextics(random.Random(seed), central=False)
    rows = [(i, m) for i in range(15) for m in monomials_up_to(2)]
    mons, index, mat = build(sextics, rows)
    _, pivots = row_reduce(mat)
    pivot_set = set(pivots)
    basis = [mons[c] for c in range(len(mons)) if c not in pivot_set]
    assert len(basis) == 64, f"expected 64 standard monomials, got {len(basis)}"
    _, reducible = action_sets(basis)
    keep = list(range(len(rows)))
    assert reduces(mat, index, mons, basis, reducible, keep), "template too small"
    for r in sorted(keep, key=lambda r: grevlex_key(rows[r][1]), reverse=True):
        trial = [k for k in keep if k != r]
        if reduces(mat, index, mons, basis, reducible, trial):
            keep = trial
    return [rows[r] for r in keep], basis, reducible


def check(template_rows, basis, reducible, seed, central):
    sextics = random_sextics(random.Random(seed), central)
    mons, index, mat = build(sextics, template_rows)
    eliminated = len(mons) - len(basis) - len(reducible)
    return (reduces(mat, index, mons, basis, reducible, list(range(len(template_rows)))),
            len(mons), eliminated)


def exps(monomials):
    return ", ".join("{%d, %d, %d}" % m for m in monomials)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="src/linecloud/solvers/p6l_template.h")
    parser.add_argument("--checks", type=int, default=6)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rows, basis, reducible = find_template(args.seed)
    ncols = len({(e[0] + m[0], e[1] + m[1], e[2] + m[2])
                 for _, m in rows for e in monomials_up_to(6)})
    for k in range(args.checks):
        ok, cols, eliminated = check(rows, basis, reducible, 1000 + k, central=(k % 2 == 0))
        print(f"check {k} ({'one camera' if k % 2 == 0 else 'rig'}): "
              f"{'ok' if ok else 'FAILED'}, {len(rows)} x {cols}, eliminated {eliminated}")
        assert ok
    eliminated = ncols - len(basis) - len(reducible)
    with open(args.out, "w") as f:
        f.write(f"""// Generated by tools/p6l_template.py (seed {args.seed}); do not edit.
// Elimination template of the p6L / m-p6L solver (solvers/p6l.cc): the 15
// sextics in the Cayley parameters (x, y, z) multiplied by monomials; action =
// multiplication by x. Monomials are exponent triples (x, y, z).
#pragma once

#include <array>

namespace linecloud::p6l_template {{

struct Exponent {{
  int x, y, z;
}};
struct Row {{
  int equation;  // which of the 15 sextics (minors in lexicographic order)
  Exponent multiplier;
}};

constexpr int kRows = {len(rows)};
constexpr int kCols = {ncols};
constexpr int kBasis = {len(basis)};
constexpr int kReducible = {len(reducible)};
constexpr int kEliminated = {eliminated};
static_assert(kEliminated + kReducible == kRows, "square elimination block");

constexpr std::array<Row, kRows> kTemplateRows = {{{{
    {", ".join("{%d, {%d, %d, %d}}" % (i, *m) for i, m in rows)}}}}};
// Standard monomials B (grevlex, largest first).
constexpr std::array<Exponent, kBasis> kBasisMonomials = {{{{
    {exps(basis)}}}}};
// x·B \\ B, in the order of B.
constexpr std::array<Exponent, kReducible> kReducibleMonomials = {{{{
    {exps(reducible)}}}}};

}}  // namespace linecloud::p6l_template
""")
    print(f"wrote {args.out}: {len(rows)} x {ncols} template, basis {len(basis)}, "
          f"reducible {len(reducible)}, eliminated {eliminated}")


if __name__ == "__main__":
    main()
