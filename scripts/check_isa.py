#!/usr/bin/env python3
"""Static check of the runtime dispatch (native/smoothffd/core/isa.hpp): no function outside the
x86-64-v3 copy (namespace sffd::isa_v3) may contain an instruction beyond x86-64-v2.

    python3 scripts/check_isa.py python/smoothffd/_core*.so [--require-v3] [--list]

Disassembles the file (objdump -d --no-show-raw-insn -C -w) and looks at every instruction of
every function whose demangled name does not mention isa_v3. Flagged (each needs more than
x86-64-v2, i.e. SSE4.2 + POPCNT + CMPXCHG16B):
  * any %ymm, %zmm or AVX-512 mask register (%k0-%k7) operand;
  * any VEX/EVEX mnemonic: every x86 mnemonic starting with 'v' except the VMX/SVM ones
    (vmcall, vmlaunch, ...) and verr/verw;
  * AVX-512 mask instructions (kmov*, kand*, kor*, ...);
  * BMI1/BMI2/LZCNT/MOVBE (andn, bextr, blsi, blsmsk, blsr, bzhi, mulx, pdep, pext, rorx, sarx,
    shlx, shrx, lzcnt, movbe). Not tzcnt: objdump prints GCC's `rep bsf` (which runs as bsf on
    older CPUs, same result for the non-zero inputs it is used for) as tzcnt.
The code that chooses a path (CPUID, xgetbv) is plain x86-64 and passes. Needs the symbol
table (an unstripped file): without it code cannot be told apart by function.
Exit status: 0 clean, 1 violations (or --require-v3 and no AVX2 code in isa_v3), 2 cannot check.
"""

import argparse
import re
import shutil
import subprocess
import sys

# VMX / SVM instructions and verr/verw: start with 'v', need no AVX.
NOT_VEX = {"verr", "verw", "vmcall", "vmlaunch", "vmresume", "vmxoff", "vmxon", "vmread",
           "vmwrite", "vmptrld", "vmptrst", "vmclear", "vmfunc", "vmrun", "vmload", "vmsave",
           "vmmcall", "vmgexit"}
BEYOND_V2_SCALAR = {"andn", "bextr", "blsi", "blsmsk", "blsr", "bzhi", "mulx", "pdep", "pext",
                    "rorx", "sarx", "shlx", "shrx", "lzcnt", "movbe"}
MASK_INSN = re.compile(r"^k(mov|and|andn|or|xor|xnor|not|test|ortest|shiftl|shiftr|add|unpck)[bwdq]*$")
WIDE_REG = re.compile(r"%(ymm|zmm)\d+|%k[0-7]\b")
FUNC = re.compile(r"^([0-9a-f]+) <(.*)>:$")
INSN = re.compile(r"^\s+([0-9a-f]+):\s+(?:(?:rep[nez]*|lock|data16|addr32|notrack|bnd|cs|ds|es|ss|fs|gs)\s+)*([a-z][a-z0-9.]*)\s*(.*)$")


def beyond_v2(mnemonic, operands):
    """Why this instruction needs more than x86-64-v2, or None."""
    if WIDE_REG.search(operands):
        return "ymm/zmm/mask register"
    m = mnemonic.split(".")[0]  # vmovss.s etc.: objdump's encoding suffixes
    if m.startswith("v") and m not in NOT_VEX:
        return "VEX/EVEX instruction"
    if MASK_INSN.match(m):
        return "AVX-512 mask instruction"
    if m in BEYOND_V2_SCALAR:
        return "BMI/LZCNT/MOVBE"
    return None


def has_symtab(path):
    out = subprocess.run(["objdump", "-h", "-t", path], capture_output=True, text=True)
    return out.returncode == 0 and "no symbols" not in out.stdout and re.search(r"\bF \.text\b", out.stdout)


def check(path, list_all=False):
    proc = subprocess.Popen(["objdump", "-d", "--no-show-raw-insn", "-C", "-w", path],
                            stdout=subprocess.PIPE, text=True, errors="replace")
    func, section = None, ""
    bad = {}          # function -> (count, first instruction, reason)
    v3_funcs, v3_avx = set(), set()
    checked = set()
    for line in proc.stdout:
        if line.startswith("Disassembly of section"):
            section = line.split()[-1].rstrip(":")
            continue
        m = FUNC.match(line)
        if m:
            func = m.group(2)
            continue
        m = INSN.match(line)
        if not m or func is None:
            continue
        mnemonic, operands = m.group(2), m.group(3)
        if "isa_v3" in func:
            v3_funcs.add(func)
            if "%ymm" in operands or mnemonic.startswith("vfmadd"):
                v3_avx.add(func)
            continue
        checked.add(func)
        why = beyond_v2(mnemonic, operands)
        if why:
            n, first, reason = bad.get(func, (0, None, None))
            bad[func] = (n + 1, first or f"{m.group(1)}: {mnemonic} {operands}".strip(), reason or why)
    if proc.wait() != 0:
        print(f"check_isa: objdump failed on {path}", file=sys.stderr)
        return 2, v3_avx
    print(f"check_isa: {path}: {len(checked)} functions outside isa_v3 checked, "
          f"{len(v3_funcs)} in isa_v3 ({len(v3_avx)} with AVX2/FMA code)")
    if list_all:
        for f in sorted(v3_funcs):
            print(f"  isa_v3: {f}")
    for f, (n, first, reason) in sorted(bad.items()):
        print(f"  BEYOND x86-64-v2 ({reason}, {n} instructions): {f}\n      first: {first}")
    return (1 if bad else 0), v3_avx


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--require-v3", action="store_true",
                    help="also fail when no isa_v3 function has AVX2/FMA code (dispatch build expected)")
    ap.add_argument("--list", action="store_true", help="list the isa_v3 functions")
    args = ap.parse_args()
    if not shutil.which("objdump"):
        print("check_isa: objdump not found (apt-get install binutils)", file=sys.stderr)
        return 2
    status = 0
    for path in args.files:
        if not has_symtab(path):
            print(f"check_isa: {path} has no symbol table (stripped?): cannot tell functions apart",
                  file=sys.stderr)
            status = max(status, 2)
            continue
        rc, v3_avx = check(path, args.list)
        if rc == 0 and args.require_v3 and not v3_avx:
            print(f"check_isa: {path}: no AVX2/FMA code in isa_v3 (built without SMOOTHFFD_DISPATCH?)")
            rc = 1
        status = max(status, rc)
    print("check_isa: " + ("OK" if status == 0 else "FAILED"))
    return status


if __name__ == "__main__":
    sys.exit(main())
