// The samples stage (plan/samples.hpp): counts, shared samples, positions and weights
// against hand-computed points, and each sample's lattice piece.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <set>

#include "smoothffd/plan/adjacency.hpp"
#include "smoothffd/plan/samples.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// The unit square as two patches 0-1-2 and 2-1-3 (z = 0.25), weights 1 + 2x + 3y.
struct Square {
  Plan plan;
  SubVertices sub;
  Square() {
    sub.position = {0, 0, 0.25, 1, 0, 0.25, 0, 1, 0.25, 1, 1, 0.25};
    for (int v = 0; v < 4; ++v) sub.weight.push_back(1 + 2 * sub.position[3 * v] + 3 * sub.position[3 * v + 1]);
    const std::vector<int> pv = {0, 1, 2, 2, 1, 3};
    EdgeTable e = build_edges(pv);
    build_adjacency(plan, pv, e, std::vector<uint8_t>(e.count(), 0), {0, 1}, {0, 0});
  }
};

// An n x n grid of quads, two patches each, its vertices wherever `place` puts them.
struct Grid {
  Plan plan;
  SubVertices sub;
  template <class Place>
  Grid(int n, Place place) {
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const std::array<double, 3> x = place(i, j);
        sub.position.insert(sub.position.end(), x.begin(), x.end());
        sub.weight.push_back(1.0);
      }
    std::vector<int> pv;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
        pv.insert(pv.end(), {a, b, d, a, d, c});
      }
    EdgeTable e = build_edges(pv);
    std::vector<int> tri(pv.size() / 3);
    for (size_t t = 0; t < tri.size(); ++t) tri[t] = (int)t;
    build_adjacency(plan, pv, e, std::vector<uint8_t>(e.count(), 0), tri, std::vector<uint8_t>(tri.size(), 0));
  }
};

// A degree-2 B-spline box on [0, 1]^3 with two spans of 1e-7 at 0.5 on every axis.
LatticeSpec tiny_spans() {
  LatticeSpec s;
  const std::vector<double> U = {0, 0, 0, 0.3, 0.5, 0.5 + 1e-7, 0.5 + 2e-7, 1, 1, 1};
  for (int a = 0; a < 3; ++a) {
    s.axes[a] = AxisBasis::bspline(2, U, 7);
    s.object_to_param[a][a] = 1.0;
  }
  return s;
}

}  // namespace

TEST(Samples, EdgeNumeratorsByHand) {
  // Over 3n: the multiples of 3 (the fitting points) and n, 2n (the constraints at 1/3, 2/3).
  EXPECT_EQ(edge_sample_numerators(3), (std::vector<int>{3, 6}));
  EXPECT_EQ(edge_sample_numerators(4), (std::vector<int>{3, 4, 6, 8, 9}));
  EXPECT_EQ(edge_sample_numerators(5), (std::vector<int>{3, 5, 6, 9, 10, 12}));
  EXPECT_EQ(edge_sample_numerators(6), (std::vector<int>{3, 6, 9, 12, 15}));
}

TEST(Samples, CountsAndSharing) {
  // n: {samples inside an edge, inside a patch, total} for 4 vertices, 5 edges, 2 patches.
  const int want[][4] = {{3, 2, 1, 4 + 5 * 2 + 2 * 1}, {4, 5, 3, 4 + 5 * 5 + 2 * 3}, {6, 5, 10, 4 + 5 * 5 + 2 * 10}};
  for (const auto& w : want) {
    Square sq;
    const FitTables fit = build_fit_tables(w[0]);
    const std::vector<double> exact = build_samples(sq.plan, fit, sq.sub);
    const Plan& p = sq.plan;
    EXPECT_EQ(p.edge_samples, w[1]) << "n = " << w[0];
    EXPECT_EQ(p.samples, w[3]) << "n = " << w[0];
    EXPECT_EQ(p.fit_degree, w[0]);
    EXPECT_EQ(p.columns, (w[0] + 1) * (w[0] + 2) / 2 + 9);
    ASSERT_EQ(exact.size(), 3u * p.samples);
    ASSERT_EQ(p.patch_samples.size(), 2u * p.columns);
    // Every sample is some patch's column; the two patches share exactly the sub-vertices 1, 2
    // and the shared edge's inner samples.
    std::set<int> used0(p.patch_samples.begin(), p.patch_samples.begin() + p.columns);
    std::set<int> used1(p.patch_samples.begin() + p.columns, p.patch_samples.end());
    std::set<int> all(used0);
    all.insert(used1.begin(), used1.end());
    EXPECT_EQ((int)all.size(), p.samples);
    EXPECT_EQ(*all.begin(), 0);
    EXPECT_EQ(*all.rbegin(), p.samples - 1);
    int shared = 0;
    for (int s : used0) shared += (int)used1.count(s);
    EXPECT_EQ(shared, 2 + w[1]) << "n = " << w[0];
    // Each patch's own samples: its corners (3), its three edges' and its inside ones.
    EXPECT_EQ((int)used0.size(), 3 + 3 * w[1] + w[2]);
  }
}

TEST(Samples, PositionsAndWeightsAreTheColumnsPoints) {
  Square sq;
  const int n = 4, N3 = 3 * n;
  const FitTables fit = build_fit_tables(n);
  const std::vector<double> exact = build_samples(sq.plan, fit, sq.sub);
  const Plan& p = sq.plan;
  const std::vector<int> pv = {0, 1, 2, 2, 1, 3};
  for (int patch = 0; patch < 2; ++patch)
    for (int k = 0; k < p.columns; ++k) {
      const int s = p.patch_samples[patch * p.columns + k];
      double want[3] = {0, 0, 0};
      for (int c = 0; c < 3; ++c)
        for (int i = 0; i < 3; ++i) want[i] += fit.numerator[3 * k + c] / double(N3) * sq.sub.position[3 * pv[3 * patch + c] + i];
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(exact[3 * s + i], want[i], 1e-15) << patch << " " << k;
        EXPECT_EQ(p.sample_position[3 * s + i], (float)exact[3 * s + i]);
      }
      EXPECT_FLOAT_EQ(p.sample_weight[s], (float)(1 + 2 * want[0] + 3 * want[1])) << patch << " " << k;
    }
  // The constraint samples of each edge, at 1/3 and 2/3 of the way from its end a.
  for (int e = 0; e < p.edges; ++e) {
    const double* a = &sq.sub.position[3 * p.edge_vertex[2 * e]];
    const double* b = &sq.sub.position[3 * p.edge_vertex[2 * e + 1]];
    for (int j = 0; j < 2; ++j) {
      const int s = p.edge_constraint[2 * e + j];
      const double t = (j + 1) / 3.0;
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(exact[3 * s + i], (1 - t) * a[i] + t * b[i], 1e-15) << e;
    }
  }
  // The fitting tables as the evaluators read them.
  EXPECT_EQ(p.fit_matrix.size(), 10u * p.columns);
  EXPECT_FLOAT_EQ(p.column_bary[0] + p.column_bary[1] + p.column_bary[2], 1.0f);
}

TEST(Samples, PiecesOfAKnownLattice) {
  // Degree 2, 5 control points: pieces (-inf, 0), [0, 1/3), [1/3, 2/3), [2/3, 1), [1, inf)
  // on every axis (outside [0, 1] the boundary weights continue).
  const LatticeSpec s = bspline_box(2, 5);
  Plan plan;
  const std::vector<double> pos = {0.5, 0.1, 0.9, 0.2, 0.4, 0.7, 0.99, 0.01, 0.34, -0.5, 1.5, 0.6};
  plan.sample_position.assign(pos.begin(), pos.end());
  locate_samples(plan, s, pos);
  ASSERT_EQ(plan.sample_piece.size(), 4u);
  EXPECT_TRUE(plan.sample_local.empty());
  auto span = [](double x) { return x < 0 ? 0 : x < 1 / 3.0 ? 1 : x < 2 / 3.0 ? 2 : x < 1 ? 3 : 4; };
  for (int k = 0; k < 4; ++k) {
    const uint32_t want = span(pos[3 * k]) | span(pos[3 * k + 1]) << 10 | span(pos[3 * k + 2]) << 20;
    EXPECT_EQ(plan.sample_piece[k], want) << k;
  }
  EXPECT_EQ(plan.sample_piece[0], 2u | 1u << 10 | 3u << 20);  // (0.5, 0.1, 0.9)
}

TEST(Samples, LocalCoordinatesWhereFloatCannotResolveTheSpans) {
  // Spans of 1e-7 at 0.5 on every axis: a float position resolves them to about a quarter.
  const LatticeSpec s = tiny_spans();
  const std::vector<double> pos = {0.5 + 0.25e-7, 0.5 + 1.5e-7, 0.4};
  EXPECT_TRUE(needs_local_coordinates(s, pos));
  EXPECT_FALSE(needs_local_coordinates(bspline_box(2, 5), pos));
  Plan plan;
  plan.sample_position.assign(pos.begin(), pos.end());
  locate_samples(plan, s, pos);
  ASSERT_EQ(plan.sample_local.size(), 3u);
  // t in the span, computed in double: (x - 0.5) / 1e-7 and (x - (0.5 + 1e-7)) / 1e-7, and
  // (0.4 - 0.3) / 0.2 in the span [0.3, 0.5).
  EXPECT_NEAR(plan.sample_local[0], 0.25, 1e-6);
  EXPECT_NEAR(plan.sample_local[1], 0.5, 1e-6);
  EXPECT_NEAR(plan.sample_local[2], 0.5, 1e-6);
}

TEST(Samples, LocatedInTheBuildAsByLocateSamples) {
  // The square moved across the knot planes of a degree-2 box (1/3, 2/3 and the box's faces)
  // and of a box of 1e-7 spans (local coordinates): build_samples given the lattice locates
  // every sample as locate_samples does from the returned positions, and indexes them as
  // without a held plan, with no held plan, with the plan of the pose before (the same
  // samples, most in the same pieces) and with one whose pieces are wrong everywhere.
  const LatticeSpec tiny = tiny_spans();
  struct Case {
    LatticeSpec lattice;
    double scale, shift;
  };
  const Case cases[] = {{bspline_box(2, 5), 1.2, -0.05}, {tiny, 4e-7, 0.5 - 1e-7}};
  for (const Case& c : cases) {
    const FitTables fit = build_fit_tables(5);
    Plan before;
    for (int pose = 0; pose < 3; ++pose) {
      Square sq;
      for (size_t i = 0; i < sq.sub.position.size(); ++i)
        sq.sub.position[i] = c.shift + c.scale * (sq.sub.position[i] + 0.01 * pose * (i % 3 == 0 ? 1 : -1));
      Plan want = sq.plan;
      const std::vector<double> exact = build_samples(want, fit, sq.sub);
      locate_samples(want, c.lattice, exact);
      Plan wrong = want;
      std::fill(wrong.sample_piece.begin(), wrong.sample_piece.end(), 0u);
      const Plan* helds[] = {nullptr, pose ? &before : nullptr, &wrong};
      for (const Plan* held : helds) {
        Plan got = sq.plan;
        const std::vector<double> kept = build_samples(got, fit, sq.sub, &c.lattice, held, pose == 1);
        EXPECT_EQ(got.sample_piece, want.sample_piece) << pose;
        EXPECT_EQ(got.sample_local, want.sample_local) << pose;
        EXPECT_EQ(got.sample_position, want.sample_position) << pose;
        EXPECT_EQ(got.sample_weight, want.sample_weight) << pose;
        EXPECT_EQ(got.patch_samples, want.patch_samples) << pose;
        EXPECT_EQ(got.edge_constraint, want.edge_constraint) << pose;
        EXPECT_EQ(kept.size(), pose == 1 ? exact.size() : 0u);
      }
      std::set<uint32_t> distinct(want.sample_piece.begin(), want.sample_piece.end());
      EXPECT_GT(distinct.size(), 1u) << "the square should cross a knot plane";
      EXPECT_EQ(!want.sample_local.empty(), c.scale < 1e-6);
      before = want;
    }
  }
}

TEST(Samples, CornersDeepInABoxLocateTheirSamplesAsTheSearch) {
  // The samples of an edge or patch whose corners lie deep inside one lattice box take its
  // pieces without a search (build_samples): the same pieces as locate_samples finds, for
  // vertices on the knot planes, off them by 1e-12 to 1e-3 of a span either way, or anywhere.
  // The box lies 100 units from the origin, where float positions resolve 8e-6 of a unit
  // (more than many of those offsets), turned about two axes, so that a parameter mixes the
  // three rounded coordinates: a sample between its corners may then lie outside their
  // parameters by that much.
  const double c = 100.5, k = 1.0;  // the box's centre and its side's inverse
  const double t1 = 0.5, t2 = 0.3;
  const double Q[3][3] = {{std::cos(t1), -std::sin(t1), 0},
                          {std::sin(t1) * std::cos(t2), std::cos(t1) * std::cos(t2), -std::sin(t2)},
                          {std::sin(t1) * std::sin(t2), std::cos(t1) * std::sin(t2), std::cos(t2)}};
  LatticeSpec s = bspline_box(2, 5);  // planes at 1/3 and 2/3 of each parameter
  for (int a = 0; a < 3; ++a) {
    for (int i = 0; i < 3; ++i) s.object_to_param[a][i] = k * Q[a][i];
    s.object_to_param[a][3] = 0.5 - k * (Q[a][0] + Q[a][1] + Q[a][2]) * c;  // the centre at 0.5
  }
  auto object = [&](const double u[3]) {  // x = c + Q^T (u - 0.5) / k
    std::array<double, 3> x;
    for (int i = 0; i < 3; ++i) {
      x[i] = c;
      for (int a = 0; a < 3; ++a) x[i] += Q[a][i] * (u[a] - 0.5) / k;
    }
    return x;
  };
  const double offsets[] = {0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-7, -1e-7, 3e-6, -3e-6, 1e-5, -1e-5,
                            5e-5, -5e-5, 1e-4, -1e-4, 1e-3, -1e-3};
  const int n_off = (int)(sizeof(offsets) / sizeof(offsets[0]));
  const FitTables fit = build_fit_tables(6);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> any(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 2 * n_off);
  for (int trial = 0; trial < 12; ++trial) {
    // Each parameter near a plane (half of them) or anywhere in the box.
    auto parameter = [&]() {
      const int j = pick(rng);
      if (j >= n_off) return any(rng);
      return (any(rng) < 0.5 ? 1.0 : 2.0) / 3.0 + offsets[j];
    };
    Grid g(12, [&](int, int) {
      const double u[3] = {parameter(), parameter(), parameter()};
      return object(u);
    });
    ASSERT_FALSE(needs_local_coordinates(s, g.sub.position));  // the pieces from float positions
    Plan want = g.plan;
    const std::vector<double> exact = build_samples(want, fit, g.sub);
    locate_samples(want, s, exact);
    Plan got = g.plan;
    build_samples(got, fit, g.sub, &s, nullptr, false);
    EXPECT_EQ(got.sample_piece, want.sample_piece) << trial;
    EXPECT_EQ(got.sample_position, want.sample_position) << trial;
  }
  // A grid well inside one box: every sample there (the shortcut's case), as the search.
  Grid inside(6, [&](int i, int j) {
    const double u[3] = {0.4 + 0.03 * i, 0.4 + 0.03 * j, 0.5};
    return object(u);
  });
  Plan want = inside.plan;
  locate_samples(want, s, build_samples(want, fit, inside.sub));
  Plan got = inside.plan;
  build_samples(got, fit, inside.sub, &s, nullptr, false);
  EXPECT_EQ(got.sample_piece, want.sample_piece);
  EXPECT_EQ(std::set<uint32_t>(got.sample_piece.begin(), got.sample_piece.end()).size(), 1u);
}
