#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Checks that the compiler vectorised the fixed-point kernels of this build.

    vectorised.py OBJDUMP LIBCYLSCAN_ALGO.a PROCESSOR

The kernels are portable C++ left to the compiler's vectoriser
(algo/fixed_kernels.cpp), so a compiler or flag change could make them scalar
and still give the same bits: only the speed would drop, and nothing else
would notice. This reads the disassembly of fixed_kernels.cpp.o and asks, for
every kernel, what share of its instructions work on vector registers:
  - aarch64: registers with a lane arrangement (v0.4s, v1.16b) or q registers.
    The kernels are built once there, for the baseline, which has NEON;
  - armv7l (Debian armhf): q registers in the NEON variant of the fold;
  - x86-64: ymm in the AVX2 variants, zmm in the AVX-512 ones. The baseline
    SSE2 variant is not checked: scalar float code uses xmm registers too,
    so the share would not tell vector code from scalar.
A scalar build of a kernel has none, a vectorised one 11-70 % (the rest is
address arithmetic, the loop's scalar tail and the dispatch), so the bound
is 8 %.
"""
import re
import subprocess
import sys

MIN_SHARE = 0.08

KERNELS = {
    "aarch64": {
        "pattern": re.compile(r"\bv\d+\.(16b|8b|8h|4h|4s|2s|2d)\b|\bq\d+\b"),
        "functions": ["fold8Baseline", "fold16Baseline", "foldPhase8Baseline",
                      "foldPhase16Baseline", "phaseBaseline", "combineBaseline"],
    },
    "armv7l": {
        # 32-bit ARM: NEON works on q (and d) registers; VFP's scalar float
        # code uses s and d registers, so only q registers tell NEON apart.
        # Only the fold has a NEON variant (algo/fixed_kernels.cpp says why).
        "pattern": re.compile(r"\bq\d+\b"),
        "functions": ["fold8Neon", "fold16Neon"],
    },
    "x86_64": {
        "pattern": None,  # per variant, below
        "functions": ["fold8Avx2", "fold16Avx2", "foldPhase8Avx2", "foldPhase16Avx2",
                      "phaseAvx2", "combineAvx2", "fold8Avx512", "fold16Avx512",
                      "foldPhase8Avx512", "foldPhase16Avx512", "phaseAvx512", "combineAvx512"],
    },
}
X86_REGISTER = {"Avx2": re.compile(r"%ymm\d+"), "Avx512": re.compile(r"%zmm\d+")}


def short_name(symbol):
    """'cylscan::algo::(anonymous namespace)::fold8Avx2(...)' -> 'fold8Avx2'."""
    symbol = symbol.replace("(anonymous namespace)::", "")
    return symbol.split("(")[0].split("::")[-1]


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    objdump, library, processor = sys.argv[1:]
    arch = {"amd64": "x86_64", "arm64": "aarch64"}.get(processor.lower(), processor.lower())
    if arch not in KERNELS:
        print(f"vectorised.py: no rule for processor '{processor}'", file=sys.stderr)
        return 2
    listing = subprocess.run([objdump, "-d", "--no-show-raw-insn", "-C", library],
                             check=True, capture_output=True, text=True).stdout
    member = None
    name = None
    total = {}
    vector = {}
    for line in listing.splitlines():
        m = re.match(r"^(\S+\.o):\s+file format", line)
        if m:
            member = m.group(1)
            continue
        if member != "fixed_kernels.cpp.o":
            continue
        m = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if m:
            name = short_name(m.group(1))
            continue
        if not name or not re.match(r"^\s+[0-9a-f]+:\t", line):
            continue
        if arch != "x86_64":
            pattern = KERNELS[arch]["pattern"]
        else:
            pattern = X86_REGISTER["Avx512" if name.endswith("Avx512") else "Avx2"]
        total[name] = total.get(name, 0) + 1
        vector[name] = vector.get(name, 0) + (1 if pattern.search(line) else 0)
    failed = 0
    for function in KERNELS[arch]["functions"]:
        if function not in total:
            print(f"FAIL {function}: not in fixed_kernels.cpp.o of {library}")
            failed += 1
            continue
        share = vector[function] / total[function]
        verdict = "ok  " if share >= MIN_SHARE else "FAIL"
        failed += share < MIN_SHARE
        print(f"{verdict} {function}: {vector[function]} of {total[function]} instructions "
              f"on vector registers ({share:.0%}; at least {MIN_SHARE:.0%})")
    print(f"{len(KERNELS[arch]['functions']) - failed} vectorised, {failed} not")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
