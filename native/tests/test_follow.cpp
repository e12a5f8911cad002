// Unit tests of follow_plan (plan/plan.hpp): a plan moved to a new pose is exactly the plan
// build_plan_like makes of the new pose (the first plan's triangles, its pieces' diagonals
// where the crossings are the same); its output topology is kept while the sub-mesh and its
// edges' flags are the same, and only then. With hold, the pieces stay while they lie in
// their knot boxes (hold_clip).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "smoothffd/core/buffer_pool.hpp"
#include "smoothffd/eval/cpu_evaluator.hpp"
#include "smoothffd/plan/plan.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// Every table of the two plans, compared value for value.
void expect_same_plan(const Plan& a, const Plan& b) {
#define SAME(f) EXPECT_TRUE(a.f == b.f) << #f
  SAME(input_vertices); SAME(sub_vertices); SAME(patches); SAME(edges); SAME(samples);
  SAME(output_vertices); SAME(output_triangles); SAME(render_vertices); SAME(level); SAME(grid);
  SAME(sample_position); SAME(sample_piece); SAME(sample_weight); SAME(sample_local);
  SAME(fit_matrix); SAME(column_bary); SAME(patch_samples);
  SAME(centre_box); SAME(centre_start); SAME(centre_row); SAME(centre_constant);
  SAME(patch_vertex); SAME(patch_edge); SAME(patch_edge_reversed); SAME(patch_render_normal);
  SAME(patch_adjust_normal); SAME(patch_face);
  SAME(edge_vertex); SAME(edge_constraint); SAME(edge_patch); SAME(edge_slot); SAME(edge_flags);
  SAME(grid_basis); SAME(local_triangles); SAME(patch_grid_vertex); SAME(output_owner);
  SAME(rest_positions); SAME(triangles); SAME(face_index); SAME(uvs); SAME(sharp_edges);
  SAME(render_owner); SAME(render_position); SAME(patch_grid_render); SAME(render_triangles);
  SAME(input_triangle_corner); SAME(input_triangle_face); SAME(patch_triangle); SAME(patch_bary);
#undef SAME
}

Triangulation triangulation_of(const Plan& p) { return {p.input_triangle_corner, p.input_triangle_face}; }

// The cube of quads around the knot planes at 0.5 of a 4-point quadratic lattice, with UVs.
InputMesh cube_with_uvs() {
  InputMesh m = cube_quads(0.2, 0.8);
  for (size_t c = 0; c < m.corner_vertex.size(); ++c) {
    m.corner_uv.push_back(0.1f * (float)(c % 4));
    m.corner_uv.push_back(0.05f * (float)c);
  }
  return m;
}

PlanOptions level(int L) {
  PlanOptions o;
  o.level = L;
  return o;
}

}  // namespace

// Every vertex moved by up to 0.004 (the cube's faces from 0.2 to 0.8, the planes at 0.5): every
// face crosses the planes as before (the two cuts of a face's diagonal through its centre stay
// within each other's snap distance), so the sub-mesh is the same and the output topology is
// kept; the plan is the fresh one's.
TEST(Follow, SmallMoveKeepsTopologyAndEqualsAFreshPlan) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m = cube_with_uvs();
  Plan plan = build_plan(m, s, level(3));
  ASSERT_GT(plan.patches, 12);  // the planes at 0.5 cut every face
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  for (int step = 0; step < 4; ++step) {
    InputMesh moved = m;
    for (double& x : moved.positions) x += jitter(rng);
    const Plan before_follow = plan;
    const std::vector<int> triangles = plan.triangles;
    const std::vector<float> rest = plan.rest_positions;
    EXPECT_TRUE(follow_plan(plan, moved, s, level(3))) << "step " << step;
    EXPECT_EQ(plan.triangles, triangles);
    EXPECT_NE(plan.rest_positions, rest);
    expect_same_plan(plan, build_plan_like(moved, s, level(3), before_follow));
  }
}

// A vertex moved across a knot plane changes which faces the plane cuts: the topology is
// built again, and the plan is still the fresh one's.
TEST(Follow, CrossingAPlaneBuildsTheTopologyAgain) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m = cube_with_uvs();
  Plan plan = build_plan(m, s, level(2));
  const int patches = plan.patches;
  InputMesh moved = m;
  moved.positions[0] = 0.6;  // vertex 0 (0.2, 0.2, 0.2) past x = 0.5
  const Plan before_follow = plan;
  EXPECT_FALSE(follow_plan(plan, moved, s, level(2)));
  EXPECT_NE(plan.patches, patches);
  expect_same_plan(plan, build_plan_like(moved, s, level(2), before_follow));
}

// A new sharp edge (one face's corner normals turned to its own normal, away from its
// neighbours') changes the edge flags and the render vertices: the topology is built again.
TEST(Follow, ANewSharpEdgeBuildsTheTopologyAgain) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh smooth = octahedron();  // centre 0.5, radius 0.4: unit vertex normals (p - 0.5) / 0.4
  for (int v : smooth.corner_vertex)
    for (int i = 0; i < 3; ++i) smooth.corner_normal.push_back((float)((smooth.positions[3 * v + i] - 0.5) / 0.4));
  InputMesh turned = smooth;
  const int* f = &smooth.corner_vertex[0];  // face 0: corners 0, 1, 2
  double n[3] = {0, 0, 0};
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 3; ++i) n[i] += smooth.positions[3 * f[c] + i] - 0.5;  // the face's normal direction
  const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 3; ++i) turned.corner_normal[3 * c + i] = (float)(n[i] / l);
  Plan plan = build_plan(smooth, s, level(2));
  EXPECT_EQ(plan.render_vertices, plan.output_vertices);  // no normal splits
  const Plan before_follow = plan;
  EXPECT_FALSE(follow_plan(plan, turned, s, level(2)));
  EXPECT_GT(plan.render_vertices, plan.output_vertices);
  expect_same_plan(plan, build_plan_like(turned, s, level(2), before_follow));
}

// The triangles stay the first plan's even where the new shape would be cut along the other
// diagonal: a quad folded along its first diagonal is triangulated along the second afresh.
TEST(Follow, KeepsTheFirstTriangulation) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m;
  m.positions = {0.3, 0.3, 0.4, 0.7, 0.3, 0.4, 0.7, 0.7, 0.4, 0.3, 0.7, 0.4};
  m.corner_vertex = {0, 1, 2, 3};
  m.face_offset = {0, 4};
  Plan plan = build_plan(m, s, level(2));
  InputMesh skew = m;
  skew.positions[3 * 1 + 0] = 0.45;  // corner 1 pulled in: the 0-2 diagonal gets a sliver
  skew.positions[3 * 1 + 1] = 0.42;
  const Plan fresh = build_plan(skew, s, level(2));
  ASSERT_NE(fresh.input_triangle_corner, plan.input_triangle_corner);
  const Plan before_follow = plan;
  follow_plan(plan, skew, s, level(2));
  EXPECT_EQ(plan.input_triangle_corner, before_follow.input_triangle_corner);
  expect_same_plan(plan, build_plan_like(skew, s, level(2), before_follow));
}

// Refused input leaves the plan as it was.
TEST(Follow, RefusesAnotherMeshAndKeepsThePlan) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m = cube_with_uvs();
  Plan plan = build_plan(m, s, level(2));
  const Plan before = plan;
  InputMesh fewer = octahedron();
  EXPECT_THROW(follow_plan(plan, fewer, s, level(2)), std::invalid_argument);
  EXPECT_THROW(follow_plan(plan, m, s, level(3)), std::invalid_argument);
  InputMesh nan = m;
  nan.positions[4] = NAN;
  EXPECT_THROW(follow_plan(plan, nan, s, level(2)), std::invalid_argument);
  expect_same_plan(plan, before);
  // A triangulation whose triangle takes a corner of another face.
  Triangulation bad = triangulation_of(plan);
  bad.corners[0] = m.face_offset[1];
  EXPECT_THROW(build_plan(m, s, level(2), &bad), std::invalid_argument);
}

// Frames of a followed plan are bitwise those of the fresh plan's (the same tables).
TEST(Follow, FramesEqualAFreshPlans) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m = cube_with_uvs();
  auto plan = std::make_shared<Plan>(build_plan(m, s, level(4)));
  InputMesh moved = m;
  for (size_t i = 0; i < moved.positions.size(); i += 3) moved.positions[i + 2] += 0.02 * moved.positions[i];
  auto fresh = std::make_shared<const Plan>(build_plan_like(moved, s, level(4), *plan));
  follow_plan(*plan, moved, s, level(4));
  std::vector<float> D = zero_values(s);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  for (float& d : D) d = u(rng);
  const CpuOut a = run_cpu(plan, D), b = run_cpu(fresh, D);
  EXPECT_EQ(a.pos, b.pos);
  EXPECT_EQ(a.nrm, b.nrm);
}

// Random polygon soups (repeated vertices, split and zero normals, UVs, weights) in random
// lattices, followed through random moves of every size: each follow is build_plan_like's
// plan, and a frame of it is finite; followed holding the pieces, it keeps them (a finite
// frame) or is that same plan.
TEST(Follow, RandomMeshesAndMoves) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  int kept = 0, rebuilt = 0, held = 0, reclipped = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const LatticeSpec s = random_lattice(rng);
    const InputMesh m = random_mesh(rng, 20, 16);
    const PlanOptions opt = level(1 + trial % 4);
    Plan plan;
    try {
      plan = build_plan(m, s, opt);
    } catch (const std::invalid_argument&) {
      continue;  // refused input (e.g. only degenerate faces) has no plan to follow
    }
    for (int step = 0; step < 3; ++step) {
      InputMesh moved = m;
      const double amount = step == 0 ? 1e-7 : step == 1 ? 1e-3 : 0.1;
      for (double& x : moved.positions) x += amount * U(rng);
      const Plan before = plan;
      const bool k = follow_plan(plan, moved, s, opt);
      (k ? kept : rebuilt)++;
      expect_same_plan(plan, build_plan_like(moved, s, opt, before));
      if (k) EXPECT_EQ(plan.triangles, before.triangles);
      // Holding: the same pieces, or where one left its box the plan without hold.
      Plan h = before;
      follow_plan(h, moved, s, opt, HoldPieces::checked);
      if (h.pieces_held) {
        ++held;
        EXPECT_EQ(h.patch_vertex, before.patch_vertex);
        EXPECT_EQ(h.patch_bary, before.patch_bary);
        const CpuOut hout = run_cpu(std::make_shared<const Plan>(h), zero_values(s));
        for (float x : hout.pos) ASSERT_TRUE(std::isfinite(x));
      } else {
        ++reclipped;
        expect_same_plan(h, plan);
      }
    }
    // The followed plan evaluates as the plan build_plan_like makes (the same tables), finite.
    const CpuOut out = run_cpu(std::make_shared<const Plan>(plan), zero_values(s));
    for (float x : out.pos) ASSERT_TRUE(std::isfinite(x));
  }
  EXPECT_GT(kept, 10);
  EXPECT_GT(rebuilt, 10);
  EXPECT_GT(held, kept);
  EXPECT_GT(reclipped, 5);
}

// A sheet of triangles whose column of vertices at x = 0.49 moves past the knot plane x = 0.5
// of a quadratic lattice (0.01 past, a fiftieth of the knot span): a new clipping cuts its faces
// otherwise, holding keeps every piece (the same sub-mesh, triangles and barycentric corners)
// and its output vertices on the input vertices are the new clipping's. Moved on until a face
// lies across the plane by a tenth of the span either side, the pieces are clipped again as
// without hold.
TEST(Follow, HoldKeepsThePiecesWhileTheyStayInTheirBoxes) {
  const LatticeSpec s = bspline_box(2, 4);  // planes at 0.5
  const InputMesh m = flat_grid(8, 0.09, 0.89);  // x, y at 0.09 + 0.1 i
  auto shifted = [&](double dx) {
    InputMesh moved = m;
    for (size_t i = 0; i < moved.positions.size(); i += 3) moved.positions[i] += dx;
    return moved;
  };
  const Plan first = build_plan(m, s, level(3));
  Plan plain = first, held = first;
  EXPECT_FALSE(follow_plan(plain, shifted(0.02), s, level(3)));
  EXPECT_FALSE(plain.pieces_held);
  EXPECT_TRUE(follow_plan(held, shifted(0.02), s, level(3), HoldPieces::checked));
  EXPECT_TRUE(held.pieces_held);
  EXPECT_EQ(held.patch_vertex, first.patch_vertex);
  EXPECT_EQ(held.patch_triangle, first.patch_triangle);
  EXPECT_EQ(held.patch_bary, first.patch_bary);
  EXPECT_EQ(held.triangles, first.triangles);
  // The input vertices' outputs: the exact FFD, as the new clipping's.
  std::vector<float> D = zero_values(s);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  for (float& d : D) d = u(rng);
  const CpuOut a = run_cpu(std::make_shared<const Plan>(held), D);
  const CpuOut b = run_cpu(std::make_shared<const Plan>(plain), D);
  for (int i = 0; i < 3 * held.input_vertices; ++i) EXPECT_NEAR(a.pos[i], b.pos[i], 1e-6f) << i;
  // Held always: the same pieces however far.
  Plan always = held;
  EXPECT_TRUE(follow_plan(always, shifted(0.06), s, level(3), HoldPieces::always));
  EXPECT_TRUE(always.pieces_held);
  EXPECT_EQ(always.patch_vertex, first.patch_vertex);
  EXPECT_EQ(always.triangles, first.triangles);
  // Far across the plane: clipped again, the plan build_plan_like makes.
  Plan before = held;
  EXPECT_FALSE(follow_plan(held, shifted(0.06), s, level(3), HoldPieces::checked));  // the face at 0.39 - 0.49 now at 0.45 - 0.55
  EXPECT_FALSE(held.pieces_held);
  expect_same_plan(held, build_plan_like(shifted(0.06), s, level(3), before));
}

// The edge tables of the input triangles and of the sub-mesh depend on connectivity alone: a
// follow takes them over while the triangles and pieces are the same, and makes new ones
// (those of its own triangles) where they are not.
TEST(Follow, KeepsTheEdgeTablesOfTheSameTriangles) {
  const LatticeSpec s = bspline_box(2, 4);
  InputMesh m = cube_with_uvs();
  Plan plan = build_plan(m, s, level(2));
  ASSERT_TRUE(plan.input_edges && plan.sub_edges);
  const auto input = plan.input_edges, sub = plan.sub_edges;
  EXPECT_EQ(sub->tri_vertex, plan.patch_vertex);
  InputMesh moved = m;
  for (double& x : moved.positions) x += 0.001;
  ASSERT_TRUE(follow_plan(plan, moved, s, level(2)));
  EXPECT_EQ(plan.input_edges, input);
  EXPECT_EQ(plan.sub_edges, sub);
  moved.positions[0] = 0.6;  // vertex 0 past x = 0.5: other pieces
  const Plan before = plan;
  ASSERT_FALSE(follow_plan(plan, moved, s, level(2)));
  EXPECT_EQ(plan.input_edges, input);
  ASSERT_NE(plan.sub_edges, sub);
  EXPECT_EQ(plan.sub_edges->tri_vertex, plan.patch_vertex);
  const EdgeTable fresh = build_edges(plan.patch_vertex);
  EXPECT_EQ(plan.sub_edges->edges.vertex, fresh.vertex);
  EXPECT_EQ(plan.sub_edges->edges.side, fresh.side);
  EXPECT_EQ(plan.sub_edges->edges.face_count, fresh.face_count);
  EXPECT_EQ(plan.sub_edges->edges.tri_edge, fresh.tri_edge);
  expect_same_plan(plan, build_plan_like(moved, s, level(2), before));
  // Another mesh of as many vertices and corners: not the first plan's triangles, whose table
  // is not taken.
  InputMesh other = m;
  std::swap(other.corner_vertex[0], other.corner_vertex[1]);
  const Plan other_plan = build_plan_like(other, s, level(2), plan);
  EXPECT_NE(other_plan.input_edges, input);
}

// A CPU evaluator takes its predecessor's sample batches and output tables over (through their
// BufferPool) exactly where the plan that followed a pose kept what they are made from, and
// frames bitwise as an evaluator that made its own.
TEST(Follow, AnEvaluatorTakesOverTheTablesThePlanKept) {
  const LatticeSpec s = bspline_box(2, 4);  // planes at 0.5
  const InputMesh m = flat_grid(8, 0.09, 0.89);
  auto shifted = [&](double d, int axis = 0) {
    InputMesh moved = m;
    for (size_t i = axis; i < moved.positions.size(); i += 3) moved.positions[i] += d;
    return moved;
  };
  std::vector<float> D = zero_values(s), D2;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  for (float& d : D) d = u(rng);
  D2 = D;
  D2[1] += 0.03f;  // the corner point moved (its reach: x, y, z < 0.5): an incremental frame
  auto plan = std::make_shared<Plan>(build_plan(m, s, level(3)));
  auto pool = std::make_shared<BufferPool>();
  // The next evaluator of `plan` from the pool: what it took over, and its frames (a whole one,
  // then an incremental one) against those of an evaluator making its own tables for a copy of
  // the plan. Returns whether it took the batches.
  auto next = [&](int batches, bool owned, const std::string& what) {
    SCOPED_TRACE(what);
    std::vector<float> pos(3 * (size_t)plan->output_vertices), nrm(9 * (size_t)plan->output_triangles);
    std::vector<float> pos2 = pos, nrm2 = nrm;
    bool took;
    {
      CpuEvaluator ev(plan, 0, "auto", pool);
      took = ev.took_sample_batches();
      if (batches >= 0) EXPECT_EQ(took, batches == 1);
      EXPECT_EQ(ev.took_output_tables(), owned);
      ev.evaluate(D.data(), pos2.data(), nrm2.data(), Frame::whole);
      pos = pos2, nrm = nrm2;
      ev.evaluate(D2.data(), pos2.data(), nrm2.data(), Frame::incremental);  // into the same arrays
      EXPECT_LT(ev.last_frame().patches, plan->patches);
    }
    const auto copy = std::make_shared<const Plan>(*plan);
    const CpuOut fresh = run_cpu(copy, D), fresh2 = run_cpu(copy, D2);
    EXPECT_EQ(pos, fresh.pos);
    EXPECT_EQ(nrm, fresh.nrm);
    EXPECT_EQ(pos2, fresh2.pos);
    EXPECT_EQ(nrm2, fresh2.nrm);
    return took;
  };
  next(0, false, "the first evaluator");
  next(1, true, "the same plan again");
  // Pieces held and every sample still in its lattice piece (moved across the grid, at z = 0.37;
  // its cuts at x, y = 0.5 stay there): both taken over.
  ASSERT_TRUE(follow_plan(*plan, shifted(0.002, 2), s, level(3), HoldPieces::checked));
  ASSERT_TRUE(plan->pieces_held);
  EXPECT_TRUE(plan->repieced_samples.empty());
  next(1, true, "a held follow");
  // Moved along it: the samples on the cut at x = 0.5 move past it, into the next piece; they
  // are batched again.
  ASSERT_TRUE(follow_plan(*plan, shifted(0.002), s, level(3), HoldPieces::checked));
  ASSERT_TRUE(plan->pieces_held);
  EXPECT_FALSE(plan->repieced_samples.empty());
  next(1, true, "a held follow, samples in other lattice pieces");
  // Pieces held across the plane at 0.5: the topology is the same, more samples are in the
  // next piece.
  ASSERT_TRUE(follow_plan(*plan, shifted(0.06), s, level(3), HoldPieces::always));
  ASSERT_TRUE(plan->pieces_held);
  next(1, true, "pieces held, samples in other lattice pieces");
  // Back and forth: each time batched again, until the batches added are too many, then made
  // anew, the frames the same throughout.
  int taken = 0, made = 0;
  for (int step = 0; step < 40; ++step) {
    ASSERT_TRUE(follow_plan(*plan, shifted(step % 2 ? 0.002 : 0.0), s, level(3), HoldPieces::always));
    (next(-1, true, "back and forth, step " + std::to_string(step)) ? taken : made)++;
  }
  EXPECT_GE(made, 1);
  EXPECT_GT(taken, 4 * made);
  // Two follows with no evaluator between them: the pool's batches are two plans old.
  ASSERT_TRUE(follow_plan(*plan, shifted(0.002), s, level(3), HoldPieces::checked));
  ASSERT_TRUE(follow_plan(*plan, shifted(0.0), s, level(3), HoldPieces::checked));
  next(0, true, "two follows");
  // Clipped again: new samples and topology.
  ASSERT_FALSE(follow_plan(*plan, shifted(0.06), s, level(3)));
  ASSERT_FALSE(plan->pieces_held);
  next(0, false, "a new clipping");
  // A plan of its own (another pose), the pool's tables being the last plan's.
  plan = std::make_shared<Plan>(build_plan(shifted(0.002), s, level(3)));
  next(0, false, "another plan");
}
