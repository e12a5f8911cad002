#!/usr/bin/env bash
# Static comparison of the inline kernel (k_inline) between two trees: compiles each tree's
# kernel source for sm_90 with native/CMakeLists.txt's CUDA flags, then prints, for every
# instantiation, ptxas's registers / spills and the SASS instruction mix (loads by space, FFMA,
# SEL, branches, local memory), and for the W1 instantiations (3 terms, boxes mode) the same
# per kernel region (sampling loop, fit + edges, finish, tessellation) from -lineinfo.
# Mode names: the new tree's k_inline<C, MODE, ...> has MODE 0 boxes, 1 weights, 2 global;
# the old one (68e6379) k_inline<C, BOXES, ...> has true (Lb1) for boxes, false (Lb0) weights.
#
#   bash bench/sass_compare.sh [OLD_TREE] [NEW_TREE]   # defaults: ab_ref (git archive of 68e6379), .
# Needs nvcc, and cuobjdump + nvdisasm (CUDA's, or the nvidia-cuda-{cuobjdump,nvdisasm} wheels'
# nvidia/cu13/bin on PATH).
set -euo pipefail
cd "$(dirname "$0")/.."
OLD=${1:-ab_ref} NEW=${2:-.}
NVCC=${NVCC:-/usr/local/cuda/bin/nvcc}
W=$(mktemp -d)
compile() {  # tree, source (under native/), name
  nice "$NVCC" -cubin -arch=sm_90 -O3 -DNDEBUG -lineinfo --use_fast_math -std=c++17 -I"$1/native" \
    -I/usr/include/eigen3 -Xptxas -v -o "$W/$3.cubin" "$1/native/$2" > "$W/$3.ptxas" 2>&1
}
src_old=smoothffd/cuda/cuda_evaluator.cu; [ -f "$OLD/native/smoothffd/cuda/inline_kernel.cu" ] && src_old=smoothffd/cuda/inline_kernel.cu
compile "$OLD" "$src_old" old &
compile "$NEW" smoothffd/cuda/inline_kernel.cu new
wait
python3 - "$W" "$OLD" "$NEW" <<'PY'
import collections, os, re, subprocess, sys
w, trees = sys.argv[1], {"old": sys.argv[2], "new": sys.argv[3]}
KEYS = ["total", "LDS", "LDC", "ULDC", "LDG", "LDL", "STL", "STS", "STG", "FFMA", "FMUL", "FADD", "SEL", "FSEL", "BRA", "MOV"]
def regs(name):
    txt, out = open(f"{w}/{name}.ptxas").read(), {}
    for m in re.finditer(r"Function properties for (\S+)\n\s+(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads\n.*?Used (\d+) registers", txt):
        out[m.group(1)] = "%3s regs, stack %s, spill st/ld %s/%s" % (m.group(5), m.group(2), m.group(3), m.group(4))
    return out
def disasm(name):  # {function: [(kernel source line, opcode)]}
    txt = subprocess.run(["nvdisasm", "-gi", "-c", "-sf", f"{w}/{name}.cubin"], capture_output=True, text=True, check=True).stdout
    res, cur, kl = {}, None, -1
    for line in txt.splitlines():
        m = re.match(r"\s*\.text\.(\S+):", line)
        if m:
            cur = m.group(1) if "k_inline" in m.group(1) else None
            if cur: res[cur] = []
            continue
        if cur is None: continue
        if "//## File" in line:  # the outermost location in the kernel's own file
            locs = [int(l) for f, l in re.findall(r'"([^"]+)", line (\d+)', line) if re.search(r"inline_kernels?\.cu", f)]
            kl = locs[-1] if locs else -1
            continue
        m = re.match(r"\s*/\*[0-9a-f]{4,}\*/\s+(?:@!?U?P\w+\s+)?([A-Z0-9_]+)", line)
        if m and m.group(1) != "NOP": res[cur].append((kl, m.group(1)))
    return res
def regions(tree):  # kernel-source line ranges of k_inline's stages, from markers in the source
    d = trees[tree] + "/native/smoothffd/cuda/"
    f = d + "inline_kernel.cu" if os.path.exists(d + "inline_kernel.cu") else d + "inline_kernels.cuh"
    lines = open(f).read().splitlines()
    at = lambda s: next(i + 1 for i, l in enumerate(lines) if s in l)
    g, s, ls, fit, fin, t = at("for (int group = blockIdx.x"), at("    if (live) {"), at("gc = lanes_sum"), at("if (live && lane < 3)"), at("if (live && lane == 0)"), at("// 4. Tessellation")
    return [("prologue", 0, g), ("sample", s, ls - 1), ("lanes_sum", ls, fit - 1), ("fit+edge", fit, fin - 1), ("finish", fin, t - 1), ("tess", t, t + 14)]
def mix(ins):
    c = collections.Counter(op for _, op in ins); c["total"] = len(ins); return c
print("%-30s %-37s" % ("instantiation", "ptxas") + " ".join("%5s" % k[:5] for k in KEYS))
d, r = {}, {}
for t in ("old", "new"):
    d[t], r[t] = disasm(t), regs(t)
    for f, ins in sorted(d[t].items()):
        tag = t + " " + re.search(r"k_inlineI(\w+?)EEEv", f).group(1)
        c = mix(ins)
        print("%-30s %-37s" % (tag, r[t].get(f, "?")) + " ".join("%5d" % c[k] for k in KEYS))
w1 = {"old": r"k_inlineILi3ELb1ELi32ELi4ELi4", "new": r"k_inlineILi3ELi0ELi32ELi4ELi4"}
print("\nW1's instantiation (3 terms, boxes) by region:")
for t in ("old", "new"):
    f = next((f for f in d[t] if re.search(w1[t], f)), None)
    if f is None: continue
    for name, lo, hi in regions(t):
        c = mix([x for x in d[t][f] if lo <= x[0] <= hi])
        print("%-30s %-37s" % (t + " " + name, "") + " ".join("%5d" % c[k] for k in KEYS))
PY
rm -rf "$W"
