"""The host a benchmark ran on, for its output: benchmark figures move with the CPU, and this
project's 2-core machine is not the same CPU from one day to the next (docs/benchmarks.md,
"2026-11-28: a different host"). Standard library only; imported by the bench_*.py scripts
beside it (python3 tools/bench_x.py puts tools/ on the path)."""
from __future__ import annotations

from pathlib import Path


def cpu_line() -> str:
    """One line naming the CPU: model name, family and model (as the hypervisor reports them),
    the L3 size and the wide-vector flags. On 2026-11-28 a family-23 host ran the unchanged
    integral kernel at about half the speed of 2026-11-25's Zen 3 host."""
    info = {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            info.setdefault(key.strip(), value.strip())
    except OSError:
        return "cpu: /proc/cpuinfo not readable"
    flags = set(info.get("flags", "").split())
    try:
        l3 = Path("/sys/devices/system/cpu/cpu0/cache/index3/size").read_text().strip()
    except OSError:
        l3 = "?"
    wide = ",".join(f for f in ("avx2", "fma", "vaes", "avx512f") if f in flags) or "none"
    return (f"cpu: {info.get('model name', '?')}, family {info.get('cpu family', '?')} model "
            f"{info.get('model', '?')}, L3 {l3}, {wide}")
