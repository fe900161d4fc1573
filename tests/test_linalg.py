"""gearjax.linalg.solve: exact against NumPy's LAPACK, implicit derivatives against central
differences, and the batched-LAPACK deadlock pattern of jaxlib's CPU backend (several
vmapped solves running at once in one program) finishing."""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.linalg import lu_factor, solve

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("n", [1, 4, 17])
@pytest.mark.parametrize("kind", ["real", "complex"])
def test_solve_matches_lapack(n, kind):
    rng = np.random.default_rng(n)
    a = rng.normal(size=(n, n)) + 3.0 * np.eye(n)
    b = rng.normal(size=(n, 3))
    if kind == "complex":
        a = a + 1j * rng.normal(size=(n, n))
    x_ref = np.linalg.solve(a, b)
    scale = np.linalg.cond(a) * np.abs(x_ref).max() * 1e-14
    assert np.abs(np.asarray(solve(a, b)) - x_ref).max() < scale
    assert np.abs(np.asarray(solve(a, b[:, 0])) - x_ref[:, 0]).max() < scale


def test_pivoting_zero_leading_entry():
    # a[0, 0] = 0: elimination without row exchange divides by zero
    a = np.array([[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [3.0, 0.0, 1.0]])
    b = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(solve(a, b), np.linalg.solve(a, b), rtol=1e-14)
    lu, perm = lu_factor(jnp.asarray(a))
    lower = np.tril(np.asarray(lu), -1) + np.eye(3)
    np.testing.assert_allclose(lower @ np.triu(np.asarray(lu)), a[np.asarray(perm)], atol=1e-15)


def test_batched_and_vmapped():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(5, 6, 6)) + 4.0 * np.eye(6)
    b = rng.normal(size=(5, 6))
    x_ref = np.linalg.solve(a, b[..., None])[..., 0]
    np.testing.assert_allclose(solve(a, b), x_ref, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(jax.vmap(solve)(a, b), x_ref, rtol=1e-12, atol=1e-13)


def test_derivatives_against_central_differences():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(5, 5)) + 3.0 * np.eye(5)
    b = rng.normal(size=5)
    da = rng.normal(size=(5, 5))
    db = rng.normal(size=5)
    f = lambda s: jnp.sum(jnp.sin(solve(a + s * da, b + s * db)))  # noqa: E731
    h = 1e-5
    fd = (f(h) - f(-h)) / (2 * h)
    assert abs(float(jax.grad(f)(0.0)) - fd) < 1e-8 * max(1.0, abs(fd))
    assert abs(float(jax.jacfwd(f)(0.0)) - fd) < 1e-8 * max(1.0, abs(fd))


def test_concurrent_batched_solves_do_not_deadlock():
    """Three (or one per CPU, plus one) independent vmapped solves in one jit: with
    jnp.linalg.solve this hangs jaxlib 0.10.2's CPU backend on a 2-core machine."""
    n_solves = max(3, (os.cpu_count() or 2) + 1)
    code = textwrap.dedent(f"""
        import jax, jax.numpy as jnp
        jax.config.update("jax_enable_x64", True)
        from gearjax.linalg import solve
        keys = jax.random.split(jax.random.PRNGKey(0), {2 * n_solves})
        a = [jax.random.normal(keys[2 * i], (256, 48, 48)) + 10 * jnp.eye(48)
             for i in range({n_solves})]
        b = [jax.random.normal(keys[2 * i + 1], (256, 48, 4)) for i in range({n_solves})]
        f = jax.jit(lambda a, b: sum(jax.vmap(solve)(x, y).sum() for x, y in zip(a, b)))
        for _ in range(3):
            f(a, b).block_until_ready()
        print("finished")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "finished" in out.stdout


def test_traced_code_uses_no_batched_lapack_solve():
    """jnp.linalg.solve / jax.scipy.linalg in the package only where the module says why it
    is safe (harmonic.py maps speeds one after the other on the CPU backend)."""
    allowed = {"harmonic.py"}
    pattern = re.compile(r"jnp\.linalg\.solve\(|jax\.scipy\.linalg|jsp\.linalg|lax\.linalg\.")
    offenders = []
    for path in (ROOT / "gearjax").rglob("*.py"):
        if path.name in allowed or path.name == "linalg.py":
            continue
        for i, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if pattern.search(code) and "``" not in code:
                offenders.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not offenders, "use gearjax.linalg.solve in traced code:\n" + "\n".join(offenders)
