"""Golden episodes (tests/sim/test_pointnav_golden.py, tests/sim/agents/test_socialnav_golden.py): the CPU kind a
hash belongs to, and the check against the hash recorded for it."""

from __future__ import annotations

from collections.abc import Callable, Mapping


def cpu_kind() -> tuple[str, str]:
    """(machine, the widest numpy SIMD target this CPU runs) naming the golden entry that applies here: numpy's
    transcendental kernels (SVML on AVX-512), and hence the doubles, depend on it."""
    import platform

    from numpy._core._multiarray_umath import __cpu_features__

    simd = next((f for f in ("AVX512_SKX", "AVX2", "ASIMD") if __cpu_features__.get(f)), "baseline")
    return platform.machine(), simd


def check_golden(
    golden: Mapping[tuple[str, str], str], digest: Callable[[], tuple[str, int]], min_steps: int, script: str
) -> None:
    """Assert that `digest()` gives this CPU kind's hash in `golden` over more than `min_steps` env steps; skip on a
    kind without one (`python <script>` prints the hash to add)."""
    import pytest

    expected = golden.get(cpu_kind())
    if not expected:
        pytest.skip(
            f"no golden hash for CPU kind {cpu_kind()}: add one computed on a behaviour-preserving commit "
            f"(python {script})"
        )
    got, steps = digest()
    assert steps > min_steps
    assert got == expected, f"episodes changed: {got} != {expected} (a speed-up changed behaviour)"
