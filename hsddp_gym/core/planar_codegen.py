"""Generate `hsddp_gym.core._planar_terms`: the planar Mini Cheetah's rigid-body terms and their partial
derivatives as straight-line code, derived symbolically (sympy) from the same kinematic tree as
[`build_pinocchio_model`][hsddp_gym.core.model.build_pinocchio_model].

Run ``python -m hsddp_gym.core.planar_codegen`` after changing the tree (not the parameters: they are inputs of
the generated functions, [`kernel_params`][hsddp_gym.core.planar_dynamics.kernel_params]). sympy is only needed
here, never at run time; ``tests/test_planar_dynamics.py`` checks the committed file is what this script generates
and checks every generated term against Pinocchio.

The tree (conventions in [`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]):
``q = [x, z, pitch, hip_f, knee_f, hip_b, knee_b]``; a rotation ``R(a)`` about +y maps a body-frame ``(px, pz)`` to
``(cos a px + sin a pz, -sin a px + cos a pz)`` (Pinocchio's ``JointModelRY``); link angles add along the chain. The
parameter vector ``p`` (13,): ``[m_trunk, I_trunk, c_trunk, m_thigh, I_thigh, c_thigh, l_thigh, m_shank, I_shank,
c_shank, l_shank, hip_offset, gravity]`` (masses [kg], inertias about the CoM [kg m^2], CoM offsets and lengths along
the link's z [m]).

Generated functions (numba ``njit``, outputs written into caller-owned arrays):

* ``terms(q (7,), v (7,), p (13,), M (7, 7), b (7,), J (4, 7), drift (4,))``: the mass matrix, the bias
  ``b = C(q, v) v + g(q)`` (so that ``M a + b = tau + J^T f``), the feet's world ``(x, z)`` Jacobians (rows
  ``[x_front, z_front, x_back, z_back]``) and their drift ``dJ/dt v``;
* ``partials(q, v, a (7,), f (4,), p, r_q (7, 7), r_v (7, 7), c_q (4, 7), c_v (4, 7))``: the partial derivatives of
  the dynamics residual ``r = M(q) a + b(q, v) - J(q)^T f`` and of the feet's accelerations ``c = J(q) a + dJ v``
  with respect to ``q`` and ``v`` at fixed ``a`` and ``f``.
"""

from __future__ import annotations

import sys
from pathlib import Path

TARGET = Path(__file__).with_name("_planar_terms.py")
SYMPY_TAG = "# generated with sympy "
PARAM_NAMES = ("m_trunk", "I_trunk", "c_trunk", "m_thigh", "I_thigh", "c_thigh", "l_thigh", "m_shank", "I_shank",
               "c_shank", "l_shank", "hip_offset", "gravity")


def derive():
    """The symbolic terms: ``(q, v, a, f, p, outputs)`` with ``outputs`` a dict name -> sympy Matrix."""
    import sympy as sp

    q = sp.Matrix(sp.symbols("q0:7", real=True))
    v = sp.Matrix(sp.symbols("v0:7", real=True))
    a = sp.Matrix(sp.symbols("a0:7", real=True))
    f = sp.Matrix(sp.symbols("f0:4", real=True))
    p = sp.symbols(" ".join(PARAM_NAMES), real=True)
    m_t, I_t, c_t, m_1, I_1, c_1, l_1, m_2, I_2, c_2, l_2, hip, grav = p

    def rot(angle, px, pz):
        return sp.Matrix([sp.cos(angle) * px + sp.sin(angle) * pz, -sp.sin(angle) * px + sp.cos(angle) * pz])

    base = sp.Matrix([q[0], q[1]])
    pitch = q[2]
    bodies = [(m_t, I_t, base + rot(pitch, 0, c_t), pitch)]  # (mass, inertia, CoM (x, z), angle)
    feet = []
    for leg, sign in ((0, 1), (1, -1)):
        hip_angle, knee_angle = q[3 + 2 * leg], q[4 + 2 * leg]
        hip_at = base + rot(pitch, sign * hip, 0)
        a1 = pitch + hip_angle
        bodies.append((m_1, I_1, hip_at + rot(a1, 0, c_1), a1))
        knee_at = hip_at + rot(a1, 0, -l_1)
        a2 = a1 + knee_angle
        bodies.append((m_2, I_2, knee_at + rot(a2, 0, c_2), a2))
        feet.append(knee_at + rot(a2, 0, -l_2))

    M = sp.zeros(7, 7)
    b = sp.zeros(7, 1)
    for mass, inertia, com, angle in bodies:
        Jp = com.jacobian(q)
        Jw = sp.Matrix([angle]).jacobian(q)
        M += mass * Jp.T * Jp + inertia * Jw.T * Jw
        com_drift = (Jp * v).jacobian(q) * v
        b += mass * Jp.T * com_drift + mass * grav * Jp[1, :].T  # gravity (0, -g): dV/dq = m g dz/dq
    J = sp.Matrix.vstack(*[foot.jacobian(q) for foot in feet])
    drift = (J * v).jacobian(q) * v
    residual = M * a + b - J.T * f
    accel = J * a + drift
    outputs = {
        "M": M, "b": b, "J": J, "drift": drift,
        "r_q": residual.jacobian(q), "r_v": residual.jacobian(v), "c_q": accel.jacobian(q), "c_v": accel.jacobian(v),
    }
    return q, v, a, f, p, outputs


def _function(name: str, args: str, inputs: list[tuple[str, list]], outputs: dict, doc: str) -> str:
    """Straight-line numba source of one function: common subexpressions first, then every output element."""
    import sympy as sp

    exprs, slots = [], []
    for out_name, matrix in outputs.items():
        for i in range(matrix.rows):
            for j in range(matrix.cols):
                exprs.append(matrix[i, j])
                slots.append(f"{out_name}[{i}, {j}]" if matrix.cols > 1 else f"{out_name}[{i}]")
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), optimizations="basic")
    from sympy.printing.pycode import PythonCodePrinter

    printer = PythonCodePrinter({"fully_qualified_modules": False})
    lines = ["@numba.njit(cache=True, fastmath=False)", f"def {name}({args}):", f'    """{doc}"""']
    for array, symbols in inputs:
        for i, s in enumerate(symbols):
            lines.append(f"    {s} = {array}[{i}]")
    for sym, expr in replacements:
        lines.append(f"    {sym} = {printer.doprint(expr)}")
    for slot, expr in zip(slots, reduced):
        lines.append(f"    {slot} = {printer.doprint(expr)}")
    return "\n".join(lines) + "\n"


def generate() -> str:
    """The source of `hsddp_gym.core._planar_terms`."""
    q, v, a, f, p, out = derive()
    params = ("p", list(p))
    terms = _function("terms", "q, v, p, M, b, J, drift", [("q", list(q)), ("v", list(v)), params],
                      {k: out[k] for k in ("M", "b", "J", "drift")},
                      "Mass matrix M (7, 7), bias b (7,), feet Jacobians J (4, 7) and drift (4,) at (q, v) (in place).")
    partials = _function("partials", "q, v, a, f, p, r_q, r_v, c_q, c_v",
                         [("q", list(q)), ("v", list(v)), ("a", list(a)), ("f", list(f)), params],
                         {k: out[k] for k in ("r_q", "r_v", "c_q", "c_v")},
                         "d(M a + b - J^T f)/d(q, v) (7, 7) and d(J a + dJ v)/d(q, v) (4, 7) at fixed a, f "
                         "(in place).")
    import sympy as sp

    header = ('"""Generated by ``python -m hsddp_gym.core.planar_codegen`` (do not edit): the planar Mini Cheetah\'s\n'
              'rigid-body terms and their partial derivatives, see :mod:`hsddp_gym.core.planar_codegen`."""\n\n'
              f"# ruff: noqa\n{SYMPY_TAG}{sp.__version__}\n"
              "from math import cos, sin\n\n"
              "import numba\n\n\n")
    return header + terms + "\n\n" + partials


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the committed file differs, write nothing")
    args = parser.parse_args(argv)
    source = generate()
    if args.check:
        same = TARGET.exists() and TARGET.read_text() == source
        print(f"{TARGET}: {'up to date' if same else 'differs from the generator'}")
        return 0 if same else 1
    tmp = TARGET.with_suffix(".tmp")
    tmp.write_text(source)
    tmp.replace(TARGET)  # atomic
    print(f"wrote {TARGET} ({source.count(chr(10))} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
