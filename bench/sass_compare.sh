#!/usr/bin/env bash
# Static comparison of the inline kernel (k_inline) between two trees: compiles each tree's
# kernel source for sm_90 with native/CMakeLists.txt's CUDA flags, then prints, for every
# instantiation, ptxas's registers / spills and the SASS instruction mix (loads by space, FFMA,
# SEL, branches, local memory), and for the W1 instantiations (3 terms, boxes mode) the same
# per kernel region (sampling loop, fit + edges, finish, tessellation) from -lineinfo, and the
# sampling loop itself (label to back branch: what one column costs, with the instructions that
# -lineinfo puts on other lines, such as addresses rebuilt in the loop). --diff also prints the
# two sampling loops' instruction sequences (registers renumbered away) as a unified diff.
# Mode names: the new tree's k_inline<C, MODE, ...> has MODE 0 boxes, 1 weights, 2 global;
# the old one (68e6379) k_inline<C, BOXES, ...> has true (Lb1) for boxes, false (Lb0) weights.
#
#   bash bench/sass_compare.sh [--diff] [OLD_TREE] [NEW_TREE]   # defaults: ab_ref (git archive of 68e6379), .
# Needs nvcc, and cuobjdump + nvdisasm (CUDA's, or the nvidia-cuda-{cuobjdump,nvdisasm} wheels'
# nvidia/cu13/bin on PATH).
set -euo pipefail
cd "$(dirname "$0")/.."
DIFF=0; [ "${1:-}" = --diff ] && { DIFF=1; shift; }
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
python3 - "$W" "$OLD" "$NEW" "$DIFF" <<'PY'
import collections, difflib, os, re, subprocess, sys
w, trees, show_diff = sys.argv[1], {"old": sys.argv[2], "new": sys.argv[3]}, sys.argv[4] == "1"
labels, text = {}, {}  # per function: label -> instruction index; the instructions' text
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
            if cur: res[cur], labels[cur], text[cur] = [], {}, []
            continue
        if cur is None: continue
        if "//## File" in line:  # the outermost location in the kernel's own file
            locs = [int(l) for f, l in re.findall(r'"([^"]+)", line (\d+)', line) if re.search(r"inline_kernels?\.cu", f)]
            kl = locs[-1] if locs else -1
            continue
        m = re.match(r"(\.L_x_\d+):", line)
        if m: labels[cur][m.group(1)] = len(res[cur])
        m = re.match(r"\s*/\*[0-9a-f]{4,}\*/\s+((?:@!?U?P\w+\s+)?([A-Z0-9_]+).*?)\s*;", line)
        if m and m.group(2) != "NOP": res[cur].append((kl, m.group(2))); text[cur].append(m.group(1))
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
def sample_loop(t, f):  # the smallest loop (label .. back branch) with 80% of the sample region
    lo, hi = next((lo, hi) for name, lo, hi in regions(t) if name == "sample")
    ins = d[t][f]
    inside = [i for i, x in enumerate(ins) if lo <= x[0] <= hi]
    best = None
    for lab, h in labels[f].items():
        for e in range(h, len(ins)):
            if "BRA" in ins[e][1] and "`(" + lab + ")" in text[f][e]:
                if sum(h <= i <= e for i in inside) >= 0.8 * len(inside) and (best is None or e - h < best[1] - best[0]):
                    best = (h, e)
    return best
print("\nW1's sampling loop (one pass: a column; 'other lines': instructions -lineinfo puts outside the sample region):")
seqs = {}
for t in ("old", "new"):
    f = next((f for f in d[t] if re.search(w1[t], f)), None)
    if f is None or sample_loop(t, f) is None: continue
    h, e = sample_loop(t, f)
    lo, hi = next((lo, hi) for name, lo, hi in regions(t) if name == "sample")
    c = mix(d[t][f][h:e + 1])
    other = sum(not lo <= x[0] <= hi for x in d[t][f][h:e + 1])
    print("%-30s %-37s" % (t + " sample loop", "%d on other lines" % other) + " ".join("%5d" % c[k] for k in KEYS))
    norm = lambda s: re.sub(r"\s+", " ", re.sub(r"\.L_x_\d+", "L", re.sub(r"\b(U?R|U?P)\d+\b", r"\1", s.replace(".reuse", ""))))
    seqs[t] = [norm(s) for s in text[f][h:e + 1]]
if len(seqs) == 2:
    sm = difflib.SequenceMatcher(None, seqs["old"], seqs["new"], autojunk=False)
    print("same instruction order (registers aside): %.1f%%" % (100 * sm.ratio()))
    if show_diff:
        sys.stdout.writelines(l + "\n" for l in difflib.unified_diff(seqs["old"], seqs["new"], "old", "new", n=2, lineterm=""))
PY
rm -rf "$W"
