// libFuzzer target: a mesh, a lattice structure and a level decoded from bytes; builds the
// plan and evaluates it with control values taken from the same bytes.
//
// Contract checked (beyond ASan/UBSan): build_plan either succeeds or throws
// std::invalid_argument (anything else is a bug), and every output position and normal is
// finite, normals unit length; the input vertices' outputs match the lattice's double
// evaluation within float rounding (check_input_vertices). B-spline knots start anywhere
// (offsets up to 1e6), with non-uniform spans from 1 down to 1e-12 (and 1e-9 of the offset)
// and repeated knots up to the degree's limit. Sizes are bounded (<= 12 vertices, <= 8 faces of <= 7
// corners, <= 5 Blender points or degree + 3 B-spline points an axis, B-spline degrees summing
// to <= 8, level <= 3) so that an input runs in milliseconds (tens under ASan).
//
// Build and run: scripts/fuzz.sh (clang++ -fsanitize=fuzzer,address,undefined).
// Reproduce a crash: build/fuzz/fuzz_plan CRASH_FILE
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <vector>

#include "smoothffd/eval/cpu_evaluator.hpp"
#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/plan/plan.hpp"

using namespace sffd;

namespace {

// Values that hit knot planes, box faces and rounding edges far more often than random doubles.
double palette_or_range(FuzzedDataProvider& fdp, double lo, double hi) {
  static const double kPalette[] = {0.0, 0.25, 0.5, 0.75, 1.0, -1.0, 1.0 / 3.0, 2.0 / 3.0,
                                    1e-7, -1e-7, 0.5 + 1e-13, 0.5 - 1e-15, 1e-300, 2.0, -2.0, 0.1};
  uint8_t mode = fdp.ConsumeIntegral<uint8_t>();
  if (mode < 96) return kPalette[mode % 16];
  return fdp.ConsumeFloatingPointInRange<double>(lo, hi);
}

[[noreturn]] void fail(const char* what, double value) {
  std::fprintf(stderr, "fuzz_plan: %s (%g)\n", what, value);
  std::abort();
}

bool decode_lattice(FuzzedDataProvider& fdp, LatticeSpec& s) {
  bool blender = fdp.ConsumeBool();
  for (int a = 0; a < 3; ++a) {
    if (blender) {
      int type = fdp.ConsumeIntegralInRange<int>(0, 3);
      int n = fdp.ConsumeIntegralInRange<int>(1, 5);
      s.axes[a] = AxisBasis::blender(BlenderInterp(type), n);
    } else {
      // Degree up to 5, but at most 8 summed over the axes: the fitting degree (and with it
      // the samples a patch) grows with the sum, and degree-5 cubes run ~1 s an input here.
      int used = 0;
      for (int b = 0; b < a; ++b) used += s.axes[b].degree();
      int p = fdp.ConsumeIntegralInRange<int>(1, std::max(1, std::min(5, 8 - used - (2 - a))));
      int n = fdp.ConsumeIntegralInRange<int>(p + 1, p + 3);
      // Non-decreasing knots from byte-sized steps (0 = a repeated knot, at most p + 1 in a row
      // at the ends and p inside, so the basis stays a B-spline one) times a scale (10^0 ..
      // 10^-12: tiny spans), from an offset (0 usually, else anything from -1e6 to 1e6:
      // knots that do not start at 0). Occasionally a raw (possibly invalid) knot vector.
      std::vector<double> U;
      double scale = std::pow(10.0, -fdp.ConsumeIntegralInRange<int>(0, 12));
      uint8_t offset_kind = fdp.ConsumeIntegral<uint8_t>();
      double x = offset_kind < 128 ? 0.0 : offset_kind < 192 ? palette_or_range(fdp, -8, 8)
                                                              : std::ldexp(fdp.ConsumeFloatingPointInRange<double>(-1, 1), fdp.ConsumeIntegralInRange<int>(0, 20));
      // Spans below 1e-9 of the offset are a few double ulps wide: even the double reference
      // cannot resolve them (find_piece's rounding allowance is a fifth of such a span).
      scale = std::fmax(scale, 1e-9 * std::fabs(x));
      if (fdp.ConsumeIntegral<uint8_t>() < 8) {
        for (int i = 0; i < n + p + 1; ++i) U.push_back(palette_or_range(fdp, -2, 2));
      } else {
        int run = 1;  // equal knots so far
        for (int i = 0; i < n + p + 1; ++i) {
          U.push_back(x);
          bool end = i + 1 <= p || i + 1 >= n;  // the next knot is among the first or last p + 1
          int step = fdp.ConsumeIntegral<uint8_t>();
          if (step == 0 && run >= (end ? p + 1 : p)) step = 16;
          run = step == 0 ? run + 1 : 1;
          x += scale * step / 16.0;
        }
      }
      s.axes[a] = AxisBasis::bspline(p, U, n);  // may throw invalid_argument: fine
    }
  }
  // Affine map object -> parameter space: usually a scaled box, sometimes a general matrix.
  bool general = fdp.ConsumeIntegral<uint8_t>() < 32;
  for (int r = 0; r < 3; ++r) {
    // Default: the cube [-1, 1]^3 maps onto the span of the axis's knot planes.
    std::vector<double> planes = s.axes[r].planes();
    double lo = planes.empty() ? 0.0 : planes.front(), hi = planes.empty() ? 1.0 : planes.back();
    for (int c = 0; c < 3; ++c)
      s.object_to_param[r][c] = general ? palette_or_range(fdp, -8, 8) : (r == c ? 0.5 * (hi - lo) : 0.0);
    s.object_to_param[r][3] = general ? palette_or_range(fdp, -8, 8) : 0.5 * (hi + lo);
  }
  return true;
}

InputMesh decode_mesh(FuzzedDataProvider& fdp) {
  InputMesh m;
  int V = fdp.ConsumeIntegralInRange<int>(1, 12);
  for (int i = 0; i < 3 * V; ++i) m.positions.push_back(palette_or_range(fdp, -2, 2));
  int F = fdp.ConsumeIntegralInRange<int>(1, 8);
  m.face_offset.push_back(0);
  for (int f = 0; f < F; ++f) {
    int n = fdp.ConsumeIntegralInRange<int>(3, 7);
    for (int k = 0; k < n; ++k) m.corner_vertex.push_back(fdp.ConsumeIntegralInRange<int>(0, V - 1));
    m.face_offset.push_back((int)m.corner_vertex.size());
  }
  size_t C = m.corner_vertex.size();
  uint8_t extras = fdp.ConsumeIntegral<uint8_t>();
  if (extras & 1)
    for (size_t i = 0; i < 3 * C; ++i) m.corner_normal.push_back((float)palette_or_range(fdp, -1, 1));
  if (extras & 2)
    for (size_t i = 0; i < 2 * C; ++i) m.corner_uv.push_back((float)palette_or_range(fdp, -1, 1));
  if (extras & 4)
    for (int i = 0; i < V; ++i) m.vertex_weight.push_back((float)palette_or_range(fdp, -2, 2));
  // Invalid on purpose (must be refused with invalid_argument, never crash).
  if (extras & 8) {
    switch (fdp.ConsumeIntegralInRange<int>(0, 4)) {
      case 0: m.corner_vertex[0] = V; break;
      case 1: m.corner_vertex[0] = -1; break;
      case 2: m.positions[0] = NAN; break;
      case 3: m.face_offset.back() -= 1; break;
      case 4: m.corner_normal.resize(m.corner_normal.size() + 1); break;
    }
  }
  return m;
}

// Output vertices [0, V) are the input vertices deformed: they must match the lattice's own
// double-precision evaluation (LatticeSpec::evaluate, which Python's lattice.evaluate calls)
// within float rounding. The float pipeline rounds the point (sample positions), its parameter
// s = A p + b and the basis, so the bound scales with the lattice's size, the point, the
// displacements and the deformation's Jacobian J (how much a rounded point moves its image):
//   |F_float - F| <= 2^-24 * 256 * ((size + |p| + |F|) * (1 + |J|) + |D|max).
// A lattice whose parameters lie far from their own spans (knots at 1e6 + [0, 1]) loses the
// spans to rounding in s and fails this.
void check_input_vertices(const InputMesh& mesh, const LatticeSpec& spec, const std::vector<float>& Df,
                          const std::vector<float>& pos) {
  const int V = (int)mesh.positions.size() / 3;
  std::vector<double> D(Df.begin(), Df.end());
  double dmax = 0;
  for (double d : D) dmax = std::fmax(dmax, std::fabs(d));
  // The lattice's size: its box in object space, from the knot domain through the inverse map.
  double size = 0;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> planes = spec.axes[a].planes();
    double width = planes.empty() ? 1.0 : planes.back() - planes.front();
    double row = 0;
    for (int c = 0; c < 3; ++c) row = std::fmax(row, std::fabs(spec.object_to_param[a][c]));
    if (row > 0) size = std::fmax(size, width / row);
  }
  const double eps = std::ldexp(1.0, -24) * 256;
  for (int v = 0; v < V; ++v) {
    const double* p = &mesh.positions[3 * (size_t)v];
    double w = mesh.vertex_weight.empty() ? 1.0 : (double)mesh.vertex_weight[v];
    double F[3], J[9];
    spec.evaluate(p, D.data(), w, F, J);
    double jn = 0, pn = 0, fn = 0, err = 0;
    for (int i = 0; i < 9; ++i) jn = std::fmax(jn, std::fabs(J[i]));
    for (int i = 0; i < 3; ++i) {
      pn = std::fmax(pn, std::fabs(p[i]));
      fn = std::fmax(fn, std::fabs(F[i]));
      err = std::fmax(err, std::fabs((double)pos[3 * (size_t)v + i] - F[i]));
    }
    if (!std::isfinite(F[0] + F[1] + F[2]) || !std::isfinite(jn)) continue;  // beyond double: nothing to compare
    double tol = eps * ((size + pn + fn) * (1 + 3 * jn) + dmax);
    if (!(err <= tol)) {
      std::fprintf(stderr, "fuzz_plan: input vertex %d at (%g, %g, %g): output (%.9g, %.9g, %.9g), lattice (%.9g, %.9g, %.9g), |J| %g, size %g\n",
                   v, p[0], p[1], p[2], pos[3 * (size_t)v], pos[3 * (size_t)v + 1], pos[3 * (size_t)v + 2], F[0], F[1], F[2], jn, size);
      fail("an input vertex's output differs from lattice evaluation by", err / tol);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider fdp(data, size);
  LatticeSpec spec;
  try {
    decode_lattice(fdp, spec);
  } catch (const std::invalid_argument&) {
    return 0;
  }
  InputMesh mesh = decode_mesh(fdp);
  PlanOptions opt;
  opt.level = fdp.ConsumeIntegralInRange<int>(0, 3);  // 0: must be refused
  if (fdp.ConsumeIntegral<uint8_t>() < 16) opt.sharp_angle_degrees = palette_or_range(fdp, 0, 180);
  std::shared_ptr<Plan> plan;
  try {
    plan = std::make_shared<Plan>(build_plan(mesh, spec, opt));
  } catch (const std::invalid_argument&) {
    return 0;
  }
  if (std::getenv("FUZZ_PLAN_VERBOSE")) {
    std::fprintf(stderr, "V=%d F=%d level=%d n=%d dims=%dx%dx%d patches=%d samples=%d out_tris=%d build_ms:",
                 (int)mesh.positions.size() / 3, (int)mesh.face_offset.size() - 1, opt.level,
                 plan->fit_degree, plan->dims[0], plan->dims[1], plan->dims[2], plan->patches,
                 plan->samples, plan->output_triangles);
    for (auto& kv : plan->build_ms) std::fprintf(stderr, " %s=%.1f", kv.first.c_str(), kv.second);
    std::fprintf(stderr, "\n");
  }
  if (plan->patches > 20000) fail("too many patches for a bounded input", plan->patches);
  if (std::getenv("FUZZ_PLAN_VERBOSE")) {
    for (int a = 0; a < 3; ++a) {
      std::fprintf(stderr, "axis %d: degree %d, %d points, planes", a, spec.axes[a].degree(), spec.axes[a].n_ctrl());
      for (double x : spec.axes[a].planes()) std::fprintf(stderr, " %.17g", x);
      std::fprintf(stderr, "; map [%.17g %.17g %.17g | %.17g]\n", spec.object_to_param[a][0],
                   spec.object_to_param[a][1], spec.object_to_param[a][2], spec.object_to_param[a][3]);
    }
  }

  std::vector<float> D(3 * (size_t)spec.count());
  for (float& d : D) d = (float)palette_or_range(fdp, -4, 4);
  std::vector<float> pos(3 * (size_t)plan->output_vertices), nrm(9 * (size_t)plan->output_triangles);
  CpuEvaluator ev(plan, 1);
  StageTimes times = ev.evaluate(D.data(), pos.data(), nrm.data(), Frame::whole);
  if (std::getenv("FUZZ_PLAN_VERBOSE")) {
    std::fprintf(stderr, "evaluate_ms:");
    for (auto& kv : times) std::fprintf(stderr, " %s=%.1f", kv.first.c_str(), kv.second);
    std::fprintf(stderr, "\n");
  }
  for (float x : pos)
    if (!std::isfinite(x)) fail("non-finite output position", x);
  check_input_vertices(mesh, spec, D, pos);
  for (size_t i = 0; i < nrm.size(); i += 3) {
    double l = std::sqrt(double(nrm[i]) * nrm[i] + double(nrm[i + 1]) * nrm[i + 1] +
                         double(nrm[i + 2]) * nrm[i + 2]);
    if (!(std::fabs(l - 1.0) < 1e-3)) fail("output normal not unit length", l);
  }
  return 0;
}
