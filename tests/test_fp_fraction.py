"""benchmarks/fp_fraction.py counts what its table says: FLOPs per instruction, the innermost vector loop."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from fp_fraction import count, flops_of, hottest_loop  # noqa: E402

# A step loop around a lane loop: the lane loop (.LBB0_2) is innermost and holds the vector body; the
# step loop (.LBB0_1) holds the same body plus a scalar remainder and must not be taken for it.
ASM = """\
.LBB0_1:
\tvmulsd\t%xmm1, %xmm2, %xmm3
.LBB0_2:
\tvmovupd\t(%rsi,%rax,8), %zmm1
\tvfmadd231pd\t%zmm1, %zmm2, %zmm3
\tvaddpd\t%zmm3, %zmm1, %zmm4
\tvmulpd\t(%rdx){1to8}, %zmm4, %zmm5
\tvdivpd\t%zmm5, %zmm1, %zmm6
\tvxorpd\t%zmm6, %zmm6, %zmm7
\tvmovupd\t%zmm7, 64(%rsp)
\tvmovupd\t128(%rsp), %zmm8
\taddq\t$8, %rax
\tjne\t.LBB0_2
\tvaddsd\t%xmm1, %xmm2, %xmm3
\tjne\t.LBB0_1
"""


def test_flops_per_instruction():
    assert flops_of("vfmadd231pd") == flops_of("vfnmsub213sd") == 2
    assert flops_of("vaddpd") == flops_of("vmulsd") == flops_of("vdivpd") == flops_of("vsqrtpd") == 1
    assert flops_of("vxorpd") == flops_of("vmovupd") == flops_of("vcmpltpd") == flops_of("vbroadcastsd") == 0


def test_the_innermost_loop_is_counted_per_lane():
    body = hottest_loop(ASM)
    assert body[0] == ".LBB0_2:" and body[-1].strip() == "jne\t.LBB0_2"
    flops, kinds, lanes = count(body)
    assert lanes == 8
    assert flops == 8 * (2 + 1 + 1 + 1)  # fma, add, mul, div on 8 lanes each
    assert kinds == {"fma": 1, "add/sub/mul": 2, "div/sqrt": 1, "other": 4, "spill": 2}
