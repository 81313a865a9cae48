"""What fraction of the core's peak floating-point throughput the block kernels reach (issue 22, item 3).

Run:  python benchmarks/fp_fraction.py [--methods seed_next,rk4,lie_poisson] [--lanes 64] [--steps 20000]

For each method, the bare lane loop of the heavy top (benchmarks/profile_block.py ``_plain_loop``: the
vectorised pass the block kernels run, without sampling and checkpoint) is compiled and:

- its **FLOPs per lane-step** are counted in the machine code numba emits: the innermost loop with the
  most packed (zmm) floating-point instructions is the vector body, one iteration of which advances
  8 lanes one step; add, sub, mul, div, sqrt, min and max count 1 FLOP per lane, the fused
  multiply-adds (vfmadd..., vfnmsub...) 2; sign flips, blends, compares and loads count none;
- its **time per lane-step** is measured (one thread, median of ``--repeat``);
- the **clock** is measured with a chain of dependent scalar additions (each waits for the last: 3
  cycles of FADD latency per addition on AMD Zen 3/4, Agner Fog's instruction tables), since this
  virtual machine shows neither the clock (/proc/cpuinfo) nor hardware counters (``perf stat``:
  "not supported"), and llvm-mca 14 here has no Zen 4 model (and its Zen 3 one no AVX-512).

Achieved FLOP/cycle = FLOPs per lane-step / (ns per lane-step x GHz); the **peak** is 16 double-precision
FLOP/cycle (two 256-bit FMA pipes; a 512-bit operation occupies both halves).  The table also gives the
FLOP floor (the time the counted FLOPs take at peak) and the mix of instructions: divisions and square
roots run at a fraction of that rate (Zen 4 vdivpd zmm: one per ~5 cycles), so a kernel with many of
them cannot reach the FMA peak.
"""

import argparse
import re
import time

import numba
import numpy as np
from numba import njit
from profile_block import _plain_loop, block, timed

from gyrolab.kernels.lanes import lane_step
from gyrolab.kernels.registry import METHODS, uses_blocks

PEAK_FLOP_PER_CYCLE = 16  # Zen 4: 2 FMA pipes x 4 doubles (256 bit) x 2 FLOPs; zmm ops take both halves
FADD_LATENCY_CYCLES = 3
LANES = {"zmm": 8, "ymm": 4, "xmm": 2}
JUMP = re.compile(r"^\s+j[a-z]+\s+(\.LBB\d+_\d+)\s*$")
LABEL = re.compile(r"^(\.LBB\d+_\d+):")
INSTRUCTION = re.compile(r"^\s+(v[a-z0-9]+)\s+(.*)$")


def flops_of(mnemonic):
    """FLOPs per lane of one x86 vector/scalar double instruction (0: not arithmetic)."""
    if not (mnemonic.endswith("pd") or mnemonic.endswith("sd")):
        return 0
    if mnemonic.startswith(("vfmadd", "vfmsub", "vfnmadd", "vfnmsub")):
        return 2
    if mnemonic.startswith(("vadd", "vsub", "vmul", "vdiv", "vsqrt", "vmin", "vmax")):
        return 1
    return 0


def hottest_loop(asm):
    """The lines of the innermost loop with the most zmm instructions: each backward jump to a label
    closes a loop from that label to the jump; a loop that holds another is not innermost."""
    lines = asm.splitlines()
    labels = {LABEL.match(line).group(1): i for i, line in enumerate(lines) if LABEL.match(line)}
    loops = set()
    for i, line in enumerate(lines):
        jump = JUMP.match(line)
        if jump and jump.group(1) in labels and labels[jump.group(1)] < i:
            loops.add((labels[jump.group(1)], i))
    innermost = [(a, b) for a, b in loops if not any(a <= c and d <= b and (c, d) != (a, b) for c, d in loops)]
    a, b = max(sorted(innermost), key=lambda ab: sum("zmm" in line for line in lines[ab[0] : ab[1] + 1]))
    return lines[a : b + 1]


def count(body):
    """(FLOPs, {kind: instructions}, lanes) of one iteration of ``body``: kinds fma, add/sub/mul,
    div/sqrt, other (vector instructions that do no arithmetic: loads, stores, sign flips, compares) and
    spill (those of them that move a zmm register to or from the stack); lanes: the widest register
    its arithmetic uses."""
    flops, kinds, width = 0, {"fma": 0, "add/sub/mul": 0, "div/sqrt": 0, "other": 0, "spill": 0}, 1
    for line in body:
        match = INSTRUCTION.match(line)
        if not match:
            continue
        mnemonic, operands = match.groups()
        if "(%rsp)" in operands and "zmm" in operands and mnemonic.startswith("vmov"):
            kinds["spill"] += 1  # a vector register stored to or reloaded from the stack
        per_lane = flops_of(mnemonic)
        if not per_lane:
            kinds["other"] += 1
            continue
        lanes = next((n for reg, n in LANES.items() if reg in operands), 1) if mnemonic.endswith("pd") else 1
        width = max(width, lanes)
        flops += per_lane * lanes
        if mnemonic.startswith(("vdiv", "vsqrt")):
            kinds["div/sqrt"] += 1
        elif per_lane == 2:
            kinds["fma"] += 1
        else:
            kinds["add/sub/mul"] += 1
    return flops, kinds, width


@njit
def _dependent_adds(n, x, y):
    for _ in range(n):
        x = x + y  # each addition waits for the previous one: FADD latency bound (no fastmath)
    return x


def clock_ghz(n=200_000_000, repeat=5):
    """The core's clock (GHz) from a chain of ``n`` dependent scalar additions, median of ``repeat``."""
    _dependent_adds(10, 0.0, 1e-9)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        _dependent_adds(n, 0.0, 1e-9)
        times.append(time.perf_counter() - start)
    return n * FADD_LATENCY_CYCLES / float(np.median(times)) / 1e9


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default="seed_next,rk4,lie_poisson")
    parser.add_argument("--lanes", type=int, default=64)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    names = args.methods.split(",")
    for name in names:
        if name not in METHODS or not uses_blocks(METHODS[name]):
            lane = sorted(n for n, module in METHODS.items() if uses_blocks(module))
            parser.exit(2, f"fp_fraction: {name!r} is not a method with a block kernel; one of {', '.join(lane)}\n")
    numba.set_num_threads(1)
    ghz = clock_ghz()
    peak = PEAK_FLOP_PER_CYCLE * ghz  # GFLOP/s per core
    n, m = args.lanes, args.steps
    print(f"# heavy top (50 Hz, 45 deg, dt = 1e-4 s), {n} lanes, {m} steps, 1 thread, medians of {args.repeat}")
    print(f"# clock {ghz:.2f} GHz (dependent additions, {FADD_LATENCY_CYCLES} cycles each); peak ", end="")
    print(f"{PEAK_FLOP_PER_CYCLE} FLOP/cycle = {peak:.1f} GFLOP/s per core\n")
    print(
        "| method | FLOPs per lane-step | fma / add-sub-mul / div-sqrt / other (of them spills) per 8 lanes "
        "| ns per lane-step | FLOP floor (ns) | GFLOP/s | fraction of peak |"
    )
    print("|---|---:|---|---:|---:|---:|---:|")
    for name in names:
        step = METHODS[name].step
        loop = _plain_loop(lane_step(step))
        W, Q, B, DT, _, _ = block(n)
        ns = timed(lambda k: loop(W, Q, B, DT, n, k), n, m, args.repeat)
        flops, kinds, width = count(hottest_loop(loop.inspect_asm(loop.signatures[0])))
        per_step = flops / width
        achieved = per_step / ns  # GFLOP/s
        floor = per_step / peak
        mix = (
            " / ".join(str(kinds[k]) for k in ("fma", "add/sub/mul", "div/sqrt"))
            + f" / {kinds['other']} ({kinds['spill']})"
        )
        print(f"| {name} | {per_step:.0f} | {mix} | {ns:.2f} | {floor:.2f} | {achieved:.1f} | {achieved / peak:.0%} |")


if __name__ == "__main__":
    main()
