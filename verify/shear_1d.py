#!/usr/bin/env python3
"""1-D analysis of chapter-2 experiment 2 (sheared textile), for docs/notes/verification.md.

With inextensible rows and fibres the discrete sheared sheet is 1-D: row j
translates by w_j along the fixed edge. The shear energy of docs/model.md §2.2 with
Alg. 2's stencil is sum_j 1/2 mu gamma_j^2 l^2 with the central difference
gamma_j = (w_{j+1} - w_{j-1})/2l (one-sided on the first and last rows), and
uniform mass lumping loads every row with f l^2. Small angles: this is a
linear system for w. The script prints, for n = 5 ... 1025 rows:
  - e_rms of w against the continuum w(s) = (f/mu)(L s - s^2/2), and the rate;
  - the amplitude of the odd-even (checkerboard) component of the error;
  - sum dw^2/2l, the contraction of inextensible fibres, against the
    continuum value (f/mu)^2 L^3/6: it converges to ~1.25x, not to 1.

Usage: python3 verify/shear_1d.py   (needs numpy)
"""
import numpy as np

F, MU, L = 10.0, 100.0, 1.0


def solve(n):
    l = L / (n - 1)
    s = np.arange(n) * l
    g = np.zeros((n, n))
    for j in range(n):
        if j == 0:
            g[j, 1], g[j, 0] = 1 / l, -1 / l
        elif j == n - 1:
            g[j, n - 1], g[j, n - 2] = 1 / l, -1 / l
        else:
            g[j, j + 1], g[j, j - 1] = 1 / (2 * l), -1 / (2 * l)
    k = MU * l * l * g.T @ g
    b = np.full(n, F * l * l)
    w = np.zeros(n)
    w[1:] = np.linalg.solve(k[1:, 1:], b[1:])  # row 0 is fixed
    exact = (F / MU) * (L * s - s * s / 2)
    return l, w, exact


def main():
    prev = None
    print(f"{'n':>5} {'e_rms(w)':>10} {'rate':>5} {'checkerboard':>12} {'contraction/continuum':>22}")
    for n in [5, 9, 17, 33, 65, 129, 257, 513, 1025]:
        l, w, exact = solve(n)
        d = w - exact
        e = np.sqrt(np.mean(d * d))
        smooth = np.convolve(d, [0.25, 0.5, 0.25], mode="same")
        checker = np.abs((d - smooth)[2:-2]).max() if n > 5 else float("nan")
        contraction = (np.diff(w) ** 2).sum() / (2 * l)
        rate = "" if prev is None else f"{np.log2(prev / e):.2f}"
        print(f"{n:>5} {e:>10.3e} {rate:>5} {checker:>12.2e} {contraction / ((F / MU) ** 2 * L ** 3 / 6):>22.3f}")
        prev = e


if __name__ == "__main__":
    main()
