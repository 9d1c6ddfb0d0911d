// The choice of preconditioner changes the cost of a step, not its answer
// (docs/model.md §5): trajectories with none, Jacobi, IC(0), the CHOLMOD factor and
// BoomerAMG agree to within what the CG tolerance allows; the factor makes a
// solve without contacts converge in one iteration; and the parallel kernels
// (A·x over three columns, force terms above 20 000 particles) give the
// serial result bit for bit, for any thread count.
//
// Tolerance of the trajectory comparison: each solve stops at
// ‖r‖₂ ≤ η‖b‖₂ (docs/model.md §5), so its velocity differs from the exact solution by
// at most ‖A⁻¹‖ η ‖b‖₂ ≤ η ‖b‖₂/m_min, and ‖b‖₂ ≤ m_max √(3N) v_max (+ the
// force impulses, of the same order here). Two preconditioners differ by
// twice that per solve; over t_end this moves positions by at most
// 2 t_end η √(3N) v_max (the methods are stable, so errors do not grow
// faster). With η = 1e-9, N = 400, v_max ≤ 5 m/s (g·t plus swinging for
// t ≤ 0.3 s) and t_end = 0.3 s: 2·0.3·1e-9·34.6·5 ≈ 1.0e-7 m for the whole
// vector, so the rms over particles is bounded by 1e-7 m / √N = 5e-9 m.
// Fixed-point methods (BDF(2)) stop their iteration by the same CG rule, so
// the same bound applies to their converged iterates.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <utility>

#include <fmt/format.h>

#include "verify/test_metrics.h"
#include "model/particle_system.h"
#include "solver/cholesky.h"
#include "solver/integrator.h"
#include "solver/run.h"
#include "verify/test_scenes.h"

namespace clothbench {
namespace {

const std::vector<PreconditionerType> kAll = {PreconditionerType::kNone, PreconditionerType::kJacobi,
                                              PreconditionerType::kIc0, PreconditionerType::kCholesky,
                                              PreconditionerType::kAmg};

// CG iterations of a filtered solve of A v = b (A, its preconditioner from
// `sm`) from v = 0 at η = 1e-10; the solve must converge.
int PcgIterations(const SystemMatrix& sm, const MatrixN3& b, const VelocityFilter& filter) {
  const int n = static_cast<int>(b.rows());
  MatrixN3 v = MatrixN3::Zero(n, 3);
  PcgWorkspace work(n);
  const PcgSummary s = FilteredPcg(sm.matrix(), b, filter, sm.preconditioner(), {1e-10, 1000}, &v, &work);
  EXPECT_EQ(s.status, PcgStatus::kConverged);
  return s.iterations;
}

double RmsDifference(const MatrixN3& a, const MatrixN3& b) {
  return (a - b).norm() / std::sqrt(static_cast<double>(a.rows()));
}

class PreconditionerTrajectoryTest : public ::testing::TestWithParam<Method> {};

TEST_P(PreconditionerTrajectoryTest, SameTrajectoryWithinTheCgTolerance) {
  Scene scene = DefaultScene();  // 20×20 swinging sheet, two fixed corners
  scene.t_end = 0.3;
  scene.frame_dt = 0.05;
  scene.solver.cg_tolerance = 1e-9;
  scene.solver.cg_max_iterations = 5000;
  std::vector<Trajectory> runs;
  for (PreconditionerType type : kAll) {
    scene.solver.preconditioner = type;
    const ParticleSystem sys(scene);
    const RunSummary r = RunIntegrator(sys, GetParam(), {0.005, scene.t_end, scene.frame_dt});
    ASSERT_TRUE(r.ok()) << ToString(type) << ": " << testing::Brief(r);
    runs.push_back(r.trajectory);
  }
  const double bound = 5e-9;  // see the file comment
  double worst = 0.0;
  for (std::size_t k = 1; k < runs.size(); ++k)
    for (std::size_t f = 0; f < runs[0].positions.size(); ++f) {
      worst = std::max(worst, RmsDifference(runs[k].positions[f], runs[0].positions[f]));
      EXPECT_LT(RmsDifference(runs[k].positions[f], runs[0].positions[f]), bound)
          << ToString(kAll[k]) << " vs none at t = " << runs[0].times[f];
    }
  RecordProperty("max_rms_difference_m", fmt::format("{:.3e}", worst));
  EXPECT_GT(worst, 0.0);  // the preconditioners really did run different iterations
}

INSTANTIATE_TEST_SUITE_P(Methods, PreconditionerTrajectoryTest,
                         ::testing::Values(Method::kSbdf2, Method::kBdf2, Method::kImplicitMidpoint),
                         [](const auto& p) { return std::string(ToString(p.param)); });

// Without contacts the factor of A_F is the exact inverse of the filtered
// system (the fixed particles are decoupled), so every SBDF(2) solve takes
// exactly one CG iteration (zero would need the predictor to be exact).
TEST(CholeskyPreconditioner, OneIterationPerSolveWithoutContacts) {
  Scene scene = DefaultScene();
  scene.t_end = 0.2;
  scene.solver.preconditioner = PreconditionerType::kCholesky;
  for (CholeskyOrdering ordering : {CholeskyOrdering::kMetis, CholeskyOrdering::kAmd}) {
    scene.solver.cholesky_ordering = ordering;
    const ParticleSystem sys(scene);
    const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {0.01, scene.t_end, scene.frame_dt});
    ASSERT_TRUE(r.ok()) << testing::Brief(r);
    EXPECT_EQ(r.cg_iterations, r.steps) << ToString(ordering);
    EXPECT_GT(r.setup_time_s, 0.0);
  }
}

// With contacts the filter changes every step and the factor is only a
// preconditioner; the run must still land on the same trajectory. The
// round table at η = 1e-9: contact sets are decided from positions, which
// agree to ~1e-9 m, far below the collision distance (1e-2 m), so the same
// particles are constrained and the bound of the file comment applies
// (v_max ≤ 5 m/s over 0.3 s).
TEST(CholeskyPreconditioner, SameTrajectoryWithContacts) {
  Scene scene = BuiltinScene("round_table");
  scene.t_end = 0.3;
  scene.frame_dt = 0.1;
  scene.solver.cg_tolerance = 1e-9;
  scene.solver.cg_max_iterations = 5000;
  std::vector<Trajectory> runs;
  // The factor with and without contact factors (Preconditioner), then AMG.
  for (PreconditionerType type : {PreconditionerType::kIc0, PreconditionerType::kCholesky, PreconditionerType::kCholesky,
                                  PreconditionerType::kAmg}) {
    scene.solver.preconditioner = type;
    scene.solver.contact_factors = runs.size() != 2;
    const ParticleSystem sys(scene);
    const RunSummary r = RunIntegrator(sys, Method::kSbdf2, {0.01, scene.t_end, scene.frame_dt});
    ASSERT_TRUE(r.ok()) << ToString(type) << ": " << testing::Brief(r);
    runs.push_back(r.trajectory);
  }
  for (std::size_t k = 1; k < runs.size(); ++k)
    EXPECT_LT(RmsDifference(runs[k].positions.back(), runs[0].positions.back()), 5e-9) << k;
}

// Repetition: the contact factors and the prefiltered AMG choose between
// row changes (a kept hierarchy) and a refactorisation (a setup) by counts
// (kModifyRowsPerSqrtN, kSetupVCycles), never by measured time, so the same
// run repeated in one process ends bit for bit where it ended before.
// (With times deciding, the round table's runs could differ by ~1e-9 m.)
TEST(ContactPreconditioners, RepeatedRunsAreBitIdentical) {
  Scene scene = BuiltinScene("round_table");
  scene.t_end = 0.4;
  scene.frame_dt = 0.4;
  for (PreconditionerType type : {PreconditionerType::kCholesky, PreconditionerType::kAmg}) {
    scene.solver.preconditioner = type;
    const ParticleSystem sys(scene);
    const RunSummary a = RunIntegrator(sys, Method::kSbdf2, {0.01, scene.t_end, scene.frame_dt});
    const RunSummary b = RunIntegrator(sys, Method::kSbdf2, {0.01, scene.t_end, scene.frame_dt});
    ASSERT_TRUE(a.ok() && b.ok()) << ToString(type);
    EXPECT_EQ(a.cg_iterations, b.cg_iterations) << ToString(type);
    EXPECT_TRUE(a.trajectory.positions.back() == b.trajectory.positions.back()) << ToString(type);
  }
}

// The same at 10⁴ particles (the round table at 100 × 100) through the
// impact: the contact factors follow tens of thousands of contact changes
// by refactorisations and row deletes and adds, the prefiltered AMG by
// setups and kept hierarchies. Bound of the file comment
// with N = 10⁴: 2·0.3·1e-9·√(3·10⁴)·5 m / √N = 5.2e-9 m.
TEST(ContactPreconditioners, GiveTheIc0TrajectoryAt10k) {
  Scene scene = BuiltinScene("round_table");
  scene.grid.nu = scene.grid.nv = 100;
  scene.t_end = 0.3;
  scene.frame_dt = 0.3;
  scene.solver.cg_tolerance = 1e-9;
  scene.solver.cg_max_iterations = 5000;
  std::vector<RunSummary> runs;
  // IC(0), then the contact factors and the prefiltered AMG (the default
  // contact_factors = true of "cholesky" and "amg") with each frame rule.
  const std::pair<PreconditionerType, AmgFrames> settings[] = {
      {PreconditionerType::kIc0, AmgFrames::kAdaptive},      {PreconditionerType::kCholesky, AmgFrames::kAdaptive},
      {PreconditionerType::kAmg, AmgFrames::kAdaptive},      {PreconditionerType::kAmg, AmgFrames::kNearestAxis},
      {PreconditionerType::kAmg, AmgFrames::kSpread}};
  for (const auto& [type, frames] : settings) {
    scene.solver.preconditioner = type;
    scene.solver.amg_frames = frames;
    const ParticleSystem sys(scene);
    runs.push_back(RunIntegrator(sys, Method::kSbdf2, {0.01, scene.t_end, scene.frame_dt}));
    ASSERT_TRUE(runs.back().ok()) << ToString(type) << " " << ToString(frames) << ": " << testing::Brief(runs.back());
  }
  for (std::size_t k = 1; k < runs.size(); ++k) {
    EXPECT_LT(RmsDifference(runs[k].trajectory.positions.back(), runs[0].trajectory.positions.back()), 5.2e-9) << k;
    EXPECT_LT(runs[k].cg_iterations, runs[0].cg_iterations) << k;
  }
}

struct TiltedCounts {
  int without_contacts, filtered_all, spread_half, nearest_half, plain_half;
  long setups, frame_setups[2];
};

// PCG iterations of the tilted-contact systems of the tests below, on the
// default sheet at side × side particles (0: its own size).
TiltedCounts TiltedContactIterations(int side) {
  Scene scene = DefaultScene();
  if (side > 0) scene.grid.nu = scene.grid.nv = side;
  const ParticleSystem sys(scene);
  const int n = sys.num_particles();
  const Vector3 tilted = Vector3(1, 1, 1).normalized();
  VelocityFilter free, half, all;
  for (VelocityFilter* f : {&free, &half, &all}) {
    f->Reserve(n);
    for (int p : sys.fixed()) f->Fix(p);
  }
  for (int p = 0; p < n; ++p) {
    if (sys.is_fixed(p)) continue;
    all.Constrain(p, tilted, 0.0);
    if (p < n / 2) half.Constrain(p, tilted, 0.0);
  }
  MatrixN3 b(n, 3);
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) b(p, c) = std::sin(0.7 * p + 1.3 * c) + 0.1 * std::cos(0.05 * p);
  const auto iterations = [&](SystemMatrix& sm, const VelocityFilter& f) {
    EXPECT_TRUE(sm.AdaptTo(f));
    return PcgIterations(sm, b, f);
  };
  // `filtered` is set up for the whole sheet (its first setup: spread
  // frames), then for the half (the untried nearest-axis frames); `spread`
  // for the half at once (spread frames).
  SystemMatrix filtered(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix spread(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix plain(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/false);
  EXPECT_TRUE(filtered.Update(0.01) && spread.Update(0.01) && plain.Update(0.01));
  TiltedCounts c{};
  c.without_contacts = iterations(plain, free);
  c.filtered_all = iterations(filtered, all);
  c.nearest_half = iterations(filtered, half);
  c.spread_half = iterations(spread, half);
  c.plain_half = iterations(plain, half);
  const ContactFactorStats& stats = filtered.preconditioner().contact_stats();
  c.setups = stats.refactorizations;
  c.frame_setups[0] = stats.frame_setups[0];
  c.frame_setups[1] = stats.frame_setups[1];
  return c;
}

// Contacts along a tilted normal n = (1, 1, 1)/√3, which no column factor
// can decouple; the prefiltered AMG is built on S A S + (I − S) itself, in
// contact frames. On the whole default sheet (the fixed corners apart) K̂
// is A_F with one unknown of every particle decoupled, so its PCG needs
// about the iterations of the contact-free solve (+1: the decoupled
// unknowns change the coarsening). On half of it, in nearest-axis frames,
// the frames jump by 55° between the contacts and their free neighbours
// and the count rises, but stays below that of A_F's hierarchy, which does
// not see the constraints; in spread frames nothing jumps and the half
// needs no more than the whole sheet. The second setup of a preconditioner
// tries the frame mode its first did not use. (Measured: 6 contact-free and
// 6 on the tilted sheet; tilted half 7 in spread frames, 10 in nearest-axis
// frames, 12 on A_F, 33 with the hierarchy built in world rather than
// contact frames.)
TEST(AmgPreconditioner, PrefilteredHierarchySeesTiltedContacts) {
  const TiltedCounts c = TiltedContactIterations(0);
  EXPECT_LE(c.filtered_all, c.without_contacts + 1);
  EXPECT_LE(c.spread_half, c.filtered_all + 1);
  EXPECT_LT(c.nearest_half, c.plain_half);
  EXPECT_EQ(c.setups, 2);
  EXPECT_EQ(c.frame_setups[0], 1);  // nearest-axis: the half
  EXPECT_EQ(c.frame_setups[1], 1);  // spread: the whole sheet, first
}

// The same at 150 × 150 particles, where the prefiltered hierarchy is
// coarsened aggressively on its first level (solver/amg.cc,
// kAggressiveCoarseningNodes = 20000, with 2-stage extended+i
// interpolation there; A_F's hierarchy too). Aggressive coarsening costs iterations (the whole
// sheet: 9 against 7 with standard coarsening; 13 with multipass
// interpolation), and the frame jumps of nearest-axis frames cost more
// than on the small sheet, growing with N: on the tilted half 13 / 17 /
// 25 / 30 iterations at 50² / 100² / 200² / 300² in nearest-axis frames,
// 7 / 7 / 13 / 13 in spread frames, as many as on the whole sheet (with
// multipass interpolation). (Measured here: 9 contact-free, 9 on the
// tilted sheet, 9 and 23 on the half in spread and nearest-axis frames, 29
// on A_F; with A_F's hierarchy in standard coarsening 6 contact-free and
// 26 on A_F.) The
// bounds: at most twice the contact-free count plus 2 on the tilted
// sheet, the spread half at most one more than the whole sheet, and the
// nearest-axis half still fewer than A_F's hierarchy.
TEST(AmgPreconditioner, AggressivelyCoarsenedHierarchySeesTiltedContacts) {
  const TiltedCounts c = TiltedContactIterations(150);
  EXPECT_LE(c.filtered_all, 2 * c.without_contacts + 2);
  EXPECT_LE(c.spread_half, c.filtered_all + 1);
  EXPECT_LT(c.spread_half, c.nearest_half);
  EXPECT_LT(c.nearest_half, c.plain_half);
  EXPECT_EQ(c.setups, 2);
}

// The prefiltered AMG's diagnostics (Preconditioner::AmgDiagnostics), on
// half the default sheet constrained along e_x, then along (1, 1, 1)/√3, in
// nearest-axis frames:
// - off_axis counts the tilted contacts only;
// - the V-cycle factor is a contraction, smaller for the axis-aligned
//   contacts than for the tilted ones (their nearest-axis frames jump
//   against the free half's world frames; measured 0.080 and 0.52);
// - with axis_normals the tilted normals are rounded to e_x (the first of
//   three equal components), so the hierarchy is that of the e_x contacts
//   and its factor equal to theirs to rounding;
// - with frames_only the hierarchy is A_α's in the contacts' frames: in
//   world frames (axis_normals, or e_x contacts, whose nearest-axis frame
//   is the identity) both are A_α's, equal to rounding, and the tilted
//   contacts' rotated frames alone make the V-cycle slower (hypre
//   interpolates each unknown from the same unknown; a rotated frame mixes
//   x, y and z; measured 0.080 in world frames, 0.61 in the tilted ones).
TEST(AmgPreconditioner, DiagnosticsMeasureTheVCycleOfTiltedContacts) {
  const ParticleSystem sys(DefaultScene());
  const int n = sys.num_particles();
  struct Measured {
    double factor;
    int off_axis, contacts;
  };
  const auto measure = [&](const Vector3& normal, Preconditioner::AmgDiagnostics d) {
    VelocityFilter filter;
    filter.Reserve(n);
    for (int p : sys.fixed()) filter.Fix(p);
    int contacts = 0;
    for (int p = 0; p < n / 2; ++p)
      if (!sys.is_fixed(p)) {
        filter.Constrain(p, normal, 0.0);
        ++contacts;
      }
    SystemMatrix sm(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
    sm.set_amg_frames(AmgFrames::kNearestAxis);
    sm.set_amg_diagnostics(d);
    EXPECT_TRUE(sm.Update(0.01));
    EXPECT_TRUE(sm.AdaptTo(filter));
    const ContactFactorStats& stats = sm.preconditioner().contact_stats();
    EXPECT_EQ(stats.refactorizations, 1);
    return Measured{stats.cycle_factor, stats.off_axis, contacts};
  };
  const Vector3 tilted = Vector3(1, 1, 1).normalized();
  const Measured axis = measure(Vector3::UnitX(), {true, false});
  const Measured skew = measure(tilted, {true, false});
  const Measured rounded = measure(tilted, {true, true});
  EXPECT_EQ(axis.off_axis, 0);
  EXPECT_EQ(skew.off_axis, skew.contacts);
  EXPECT_EQ(rounded.off_axis, rounded.contacts);
  EXPECT_GT(axis.factor, 0.0);
  EXPECT_LT(axis.factor, skew.factor);
  EXPECT_LT(skew.factor, 1.0);
  EXPECT_NEAR(rounded.factor, axis.factor, 1e-9);
  EXPECT_TRUE(std::isnan(measure(tilted, {}).factor));  // not measured

  const Measured world = measure(tilted, {true, true, true});
  const Measured axis_frames = measure(Vector3::UnitX(), {true, false, true});
  const Measured turned = measure(tilted, {true, false, true});
  std::printf("[ diagnostics ] V-cycle factor: e_x %.3f, tilted %.3f, rounded %.3f; A_alpha alone: world %.3f, "
              "e_x frames %.3f, tilted frames %.3f\n",
              axis.factor, skew.factor, rounded.factor, world.factor, axis_frames.factor, turned.factor);
  EXPECT_EQ(turned.off_axis, turned.contacts);  // counted whatever the diagnostic
  EXPECT_NEAR(axis_frames.factor, world.factor, 1e-9);
  EXPECT_GT(world.factor, 0.0);
  EXPECT_LT(world.factor, turned.factor);
}

// The frame rule of the prefiltered AMG (Preconditioner::FrameMode): a
// first setup in spread frames, for tilted contacts on half the default
// sheet; the contacts turn to another tilted normal, and the second setup
// tries the nearest-axis frames, which need more V-cycles per solve there
// (10 against 7 PCG iterations, test PrefilteredHierarchySeesTiltedContacts);
// with the contacts unchanged, the next AdaptTo rebuilds at once, in spread
// frames again, and the one after keeps that hierarchy.
TEST(AmgPreconditioner, AHierarchyThatLosesToTheOtherFrameModeIsRebuilt) {
  const ParticleSystem sys(DefaultScene());
  const int n = sys.num_particles();
  VelocityFilter first, turned;
  for (VelocityFilter* f : {&first, &turned}) {
    f->Reserve(n);
    for (int p : sys.fixed()) f->Fix(p);
  }
  for (int p = 0; p < n / 2; ++p) {
    if (sys.is_fixed(p)) continue;
    first.Constrain(p, Vector3(1, 1, 1).normalized(), 0.0);
    turned.Constrain(p, Vector3(1, -1, 1).normalized(), 0.0);
  }
  MatrixN3 b(n, 3);
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) b(p, c) = std::sin(0.7 * p + 1.3 * c) + 0.1 * std::cos(0.05 * p);
  SystemMatrix sm(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  ASSERT_TRUE(sm.Update(0.01));
  const ContactFactorStats& stats = sm.preconditioner().contact_stats();
  ASSERT_TRUE(sm.AdaptTo(first));
  const int spread = PcgIterations(sm, b, first);
  ASSERT_TRUE(sm.AdaptTo(turned));
  const int nearest = PcgIterations(sm, b, turned);
  EXPECT_EQ(stats.frame_setups[0], 1);
  EXPECT_EQ(stats.frame_setups[1], 1);
  ASSERT_LT(spread, nearest);  // the premise: the nearest-axis frames lose here
  ASSERT_TRUE(sm.AdaptTo(turned));
  EXPECT_EQ(stats.refactorizations, 3);
  EXPECT_EQ(stats.frame_setups[1], 2);
  PcgIterations(sm, b, turned);
  ASSERT_TRUE(sm.AdaptTo(turned));
  EXPECT_EQ(stats.refactorizations, 3);
}

// A run that starts in contact tries both frame modes: once the first
// hierarchy (spread frames) has been applied, the next AdaptTo builds one
// in nearest-axis frames while that mode is untried, even with the contacts
// unchanged; without a V-cycle applied, or with a fixed frame mode, the
// hierarchy is kept.
TEST(AmgPreconditioner, AnUntriedFrameModeIsTriedAfterTheFirstSolve) {
  const ParticleSystem sys(DefaultScene());
  const int n = sys.num_particles();
  VelocityFilter filter;
  filter.Reserve(n);
  for (int p : sys.fixed()) filter.Fix(p);
  for (int p = 0; p < n / 2; ++p)
    if (!sys.is_fixed(p)) filter.Constrain(p, Vector3(1, 1, 1).normalized(), 0.0);
  MatrixN3 b(n, 3);
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) b(p, c) = std::sin(0.7 * p + 1.3 * c) + 0.1 * std::cos(0.05 * p);
  for (AmgFrames frames : {AmgFrames::kAdaptive, AmgFrames::kSpread}) {
    SystemMatrix sm(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
    sm.set_amg_frames(frames);
    ASSERT_TRUE(sm.Update(0.01));
    const ContactFactorStats& stats = sm.preconditioner().contact_stats();
    ASSERT_TRUE(sm.AdaptTo(filter));
    ASSERT_TRUE(sm.AdaptTo(filter));  // nothing applied yet: kept
    EXPECT_EQ(stats.refactorizations, 1) << ToString(frames);
    PcgIterations(sm, b, filter);
    ASSERT_TRUE(sm.AdaptTo(filter));
    if (frames == AmgFrames::kAdaptive) {
      EXPECT_EQ(stats.refactorizations, 2);
      EXPECT_EQ(stats.frame_setups[1], 1);
      EXPECT_EQ(stats.frame_setups[0], 1);
    } else {
      EXPECT_EQ(stats.refactorizations, 1);
      EXPECT_EQ(stats.frame_setups[0], 0);
    }
  }
}

// A kept prefiltered hierarchy takes changed contacts on its finest level
// (AmgPreconditioner::UpdateSystemFineLevel): tilted contacts on half the
// default sheet, then 8 more particles (4 % of the contacts, below
// kSystemKeepShare) constrained along another tilted normal. The hierarchy
// is kept (no second setup, one finest-level update) and needs at most three
// iterations more than a hierarchy set up for the new contacts, and fewer
// than A_F's. Both set up in spread frames (a first setup), and a setup
// also spreads the new contacts' directions over their free neighbours'
// frames; a kept hierarchy cannot without leaving its coarse levels'
// frames. (Measured: 10 kept, 8 set up afresh, 17 on A_F; 25 with the
// hierarchy kept but its finest level not updated. In nearest-axis
// frames, 11 kept and 11 afresh.)
TEST(AmgPreconditioner, KeptHierarchyTakesChangedContactsOnItsFinestLevel) {
  Scene scene = DefaultScene();
  const ParticleSystem sys(scene);
  const int n = sys.num_particles();
  VelocityFilter before, after;
  for (VelocityFilter* f : {&before, &after}) {
    f->Reserve(n);
    for (int p : sys.fixed()) f->Fix(p);
  }
  int added = 0;
  for (int p = 0; p < n; ++p) {
    if (sys.is_fixed(p)) continue;
    if (p < n / 2) {
      before.Constrain(p, Vector3(1, 1, 1).normalized(), 0.0);
      after.Constrain(p, Vector3(1, 1, 1).normalized(), 0.0);
    } else if (added < 8 && p % 7 == 0) {
      after.Constrain(p, Vector3(1, -1, 1).normalized(), 0.0);
      ++added;
    }
  }
  ASSERT_EQ(added, 8);
  MatrixN3 b(n, 3);
  for (int p = 0; p < n; ++p)
    for (int c = 0; c < 3; ++c) b(p, c) = std::sin(0.7 * p + 1.3 * c) + 0.1 * std::cos(0.05 * p);
  SystemMatrix kept(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix fresh(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix plain(sys, PreconditionerType::kAmg, CholeskyOrdering::kMetis, /*contact_factors=*/false);
  // Spread frames for both: in the adaptive rule the kept hierarchy's
  // first solve would make the untried nearest-axis mode's setup next.
  kept.set_amg_frames(AmgFrames::kSpread);
  fresh.set_amg_frames(AmgFrames::kSpread);
  ASSERT_TRUE(kept.Update(0.01) && fresh.Update(0.01) && plain.Update(0.01));
  ASSERT_TRUE(kept.AdaptTo(before));
  PcgIterations(kept, b, before);
  ASSERT_TRUE(kept.AdaptTo(after) && fresh.AdaptTo(after) && plain.AdaptTo(after));
  const int k = PcgIterations(kept, b, after), f = PcgIterations(fresh, b, after), a = PcgIterations(plain, b, after);
  EXPECT_EQ(kept.preconditioner().contact_stats().refactorizations, 1);
  EXPECT_EQ(kept.preconditioner().contact_stats().modifications, 1);
  EXPECT_LE(k, f + 3);
  EXPECT_LT(k, a);
}

// The fixed particles of `sys`, and half of the default sheet (its rows
// j < 10, 200 of 400 particles) constrained along `normal`.
VelocityFilter HalfSheetContacts(const Scene& scene, const ParticleSystem& sys, const Vector3& normal) {
  VelocityFilter half;
  half.Reserve(sys.num_particles());
  for (int p : sys.fixed()) half.Fix(p);
  for (int j = 0; j < 10; ++j)
    for (int i = 0; i < scene.grid.nu; ++i) half.Constrain(scene.Index(i, j), normal, 0.0);
  return half;
}

// A filter with contacts along z on half of the default sheet (200 of 400
// particles, the two fixed corners elsewhere). The contact factor of column
// z is the exact inverse of the filtered system, so the PCG converges in
// one iteration (η = 1e-10 is far above the round-off of a direct solve,
// ~1e-14); the factor of A_F alone needs several.
TEST(CholeskyPreconditioner, ContactFactorsAreExactForAxisContacts) {
  Scene scene = DefaultScene();
  const ParticleSystem sys(scene);
  const int n = sys.num_particles();
  const VelocityFilter half = HalfSheetContacts(scene, sys, Vector3(0, 0, 1));
  const MatrixN3 b = MatrixN3::Random(n, 3);
  SystemMatrix with(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix without(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/false);
  ASSERT_TRUE(with.Update(0.01) && without.Update(0.01));
  ASSERT_TRUE(with.AdaptTo(half) && without.AdaptTo(half));
  EXPECT_EQ(PcgIterations(with, b, half), 1);
  EXPECT_GT(PcgIterations(without, b, half), 3);
  EXPECT_EQ(with.preconditioner().contact_stats().refactorizations, 1);
}

// Contact frames: half of the default sheet (200 of 400 particles)
// constrained along one tilted normal (1, 1, 1)/√3. Every particle's frame
// then takes e_z to that normal (the free half takes its nearest contact's
// direction), so R_pᵀ R_q = I and the preconditioner in frames is the exact
// inverse of the filtered system: one PCG iteration (η = 1e-10, far above
// the round-off of a direct solve). The axis factors cannot decouple a
// normal 54.7° from every axis and need several. The first solve serves in
// frames, and so does every later one, with the factor kept (the contacts
// have not changed).
// The default sheet with half of its particles constrained along (1, 1, 1)/√3.
class TiltedHalfSheet : public ::testing::Test {
 protected:
  Scene scene = DefaultScene();
  const ParticleSystem sys{scene};
  const int n = sys.num_particles();
  const VelocityFilter half = HalfSheetContacts(scene, sys, Vector3(1, 1, 1).normalized());
};

TEST_F(TiltedHalfSheet, ContactFramesAreExactForOneTiltedNormal) {
  const MatrixN3 b = MatrixN3::Random(n, 3);
  SystemMatrix frames(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix axes(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  axes.set_frame_factors(false);
  ASSERT_TRUE(frames.Update(0.01) && axes.Update(0.01));
  ASSERT_TRUE(frames.AdaptTo(half) && axes.AdaptTo(half));
  EXPECT_EQ(frames.preconditioner().ServedBy(), 3);
  EXPECT_EQ(axes.preconditioner().ServedBy(), 0);  // no normal near an axis: A_F's factor
  EXPECT_EQ(PcgIterations(frames, b, half), 1);
  const int axis_iterations = PcgIterations(axes, b, half);
  EXPECT_GT(axis_iterations, 3);
  for (int step = 2; step <= 5; ++step) {
    ASSERT_TRUE(frames.AdaptTo(half));
    EXPECT_EQ(frames.preconditioner().ServedBy(), 3) << "step " << step;
    EXPECT_EQ(PcgIterations(frames, b, half), 1) << "step " << step;
  }
  EXPECT_EQ(frames.preconditioner().contact_stats().refactorizations, 1);
}

// The contact policy counts a CG iteration by the factors it reads: in
// contact frames two (A_F's factor for columns x, y, the contact factor for
// z), with A_F's factor alone one, whatever the frames do to the result.
TEST_F(TiltedHalfSheet, CountsFactorReadsForTheContactPolicy) {
  const MatrixN3 r = MatrixN3::Random(n, 3);
  MatrixN3 z(n, 3);
  SystemMatrix frames(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/true);
  SystemMatrix plain(sys, PreconditionerType::kCholesky, CholeskyOrdering::kMetis, /*contact_factors=*/false);
  ASSERT_TRUE(frames.Update(0.01) && plain.Update(0.01));
  ASSERT_TRUE(frames.AdaptTo(half) && plain.AdaptTo(half));
  ASSERT_EQ(frames.preconditioner().ServedBy(), 3);
  ASSERT_EQ(plain.preconditioner().ServedBy(), 0);
  const long f0 = frames.preconditioner().factor_reads(), p0 = plain.preconditioner().factor_reads();
  for (int k = 0; k < 5; ++k) {
    frames.preconditioner().Apply(r, &z);
    plain.preconditioner().Apply(r, &z);
  }
  EXPECT_EQ(frames.preconditioner().factor_reads() - f0, 10);
  EXPECT_EQ(plain.preconditioner().factor_reads() - p0, 5);
}

// Row deletes and adds (CholeskyFactor::DecoupleRow, CoupleRow) must leave
// the factor a refactorisation with the new decoupled set gives: four
// particles decoupled, then four others coupled back, on the default
// sheet's A_α. The solves agree to round-off (1e-9 relative allows a
// condition number of 1e4 times the ε of each of the eight modifications).
TEST(CholeskyPreconditioner, RowModificationsEqualARefactorisation) {
  Scene scene = DefaultScene();
  const ParticleSystem sys(scene);
  const int n = sys.num_particles();
  SystemMatrix sm(sys, PreconditionerType::kIc0);
  ASSERT_TRUE(sm.Update(0.01));
  const SparseMatrix& a = sm.matrix();
  std::vector<char> set(static_cast<std::size_t>(n), 0);
  for (int j = 0; j < 10; ++j)
    for (int i = 0; i < scene.grid.nu; ++i) set[static_cast<std::size_t>(scene.Index(i, j))] = 1;
  CholeskyFactor modified, fresh;
  ASSERT_TRUE(modified.Analyze(a, sys.fixed(), CholeskyOrdering::kMetis));
  ASSERT_TRUE(modified.Factorize(a, &set));
  for (int i = 0; i < 4; ++i) {
    const int p = scene.Index(i, 10);
    ASSERT_TRUE(modified.DecoupleRow(p, a));
    set[static_cast<std::size_t>(p)] = 1;
  }
  for (int i = 0; i < 4; ++i) {
    const int p = scene.Index(i, 9);
    set[static_cast<std::size_t>(p)] = 0;
    ASSERT_TRUE(modified.CoupleRow(p, a, set));
  }
  ASSERT_TRUE(fresh.Analyze(a, sys.fixed(), CholeskyOrdering::kMetis));
  ASSERT_TRUE(fresh.Factorize(a, &set));
  const MatrixN3 r = MatrixN3::Random(n, 3);
  MatrixN3 z1(n, 3), z2(n, 3);
  modified.Solve(r, &z1);
  fresh.Solve(r, &z2);
  EXPECT_LT((z1 - z2).cwiseAbs().maxCoeff(), 1e-9 * z2.cwiseAbs().maxCoeff());
}

// A·x over the three columns: bit-identical to Eigen's product and for
// 1 and 2 threads (30 000 particles, above the parallel threshold).
TEST(ParallelKernels, ProductAndForcesBitIdenticalAcrossThreadCounts) {
  const ParticleSystem sys(testing::AllTermsScene(200, 150));
  ASSERT_GE(sys.num_particles(), 20000);
  SystemMatrix sm(sys, PreconditionerType::kNone);
  ASSERT_TRUE(sm.Update(0.01));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 7, &x, &v);
  const MatrixN3 eigen = sm.matrix() * x;
  MatrixN3 y1(sys.num_particles(), 3), y2(sys.num_particles(), 3), g1(sys.num_particles(), 3),
      g2(sys.num_particles(), 3);
  testing::WithThreads(1, [&] {
    SymmetricProduct(sm.matrix(), x, &y1);
    sys.ExplicitForces(0.3, x, v, &g1);
  });
  testing::WithThreads(2, [&] {
    SymmetricProduct(sm.matrix(), x, &y2);
    sys.ExplicitForces(0.3, x, v, &g2);
  });
  EXPECT_EQ((y1 - eigen).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((y2 - eigen).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((g1 - g2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(g1.norm(), 0.0);
}

// The Cholesky solve of the three columns runs on two threads above 4096
// particles (the tree-parallel solve of the simplicial copy, or CHOLMOD's
// solve on two lanes): the same bits as on one thread, and a solve: A z = r
// to round-off (A_α's condition number ~1e4 at this size times 1e-16, far
// below 1e-9 relative). The factor of this sheet takes the tree solve.
TEST(ParallelKernels, CholeskySolveBitIdenticalAcrossThreadCounts) {
  {
    const ParticleSystem sheet(testing::AllTermsScene(100, 80));
    SystemMatrix m(sheet, PreconditionerType::kIc0);
    ASSERT_TRUE(m.Update(0.01));
    CholeskyFactor f;
    ASSERT_TRUE(f.Analyze(m.matrix(), sheet.fixed(), CholeskyOrdering::kMetis));
    ASSERT_TRUE(f.Factorize(m.matrix()));
    EXPECT_TRUE(f.tree_solve());
    const MatrixN3 r = MatrixN3::Random(sheet.num_particles(), 3);
    MatrixN3 z1(sheet.num_particles(), 3), z2(sheet.num_particles(), 3);
    testing::WithThreads(1, [&] { f.Solve(r, &z1); });
    testing::WithThreads(2, [&] { f.Solve(r, &z2); });
    EXPECT_EQ((z1 - z2).cwiseAbs().maxCoeff(), 0.0);
    MatrixN3 residual = m.matrix() * z2 - r;
    for (int p : sheet.fixed()) residual.row(p).setZero();
    EXPECT_LT(residual.norm(), 1e-9 * r.norm());
    // A row modification leaves the tree solve (the factor becomes LDLᵀ).
    ASSERT_TRUE(f.DecoupleRow(sheet.num_particles() / 2, m.matrix()));
    EXPECT_FALSE(f.tree_solve());
  }
  const ParticleSystem sys(testing::AllTermsScene(100, 80));
  ASSERT_GE(sys.num_particles(), 4096);
  SystemMatrix sm(sys, PreconditionerType::kCholesky);
  ASSERT_TRUE(sm.Update(0.01));
  MatrixN3 x, v;
  testing::PerturbedState(sys, 11, &x, &v);
  MatrixN3 z1(sys.num_particles(), 3), z2(sys.num_particles(), 3);
  testing::WithThreads(1, [&] { sm.preconditioner().Apply(x, &z1); });
  testing::WithThreads(2, [&] { sm.preconditioner().Apply(x, &z2); });
  EXPECT_EQ((z1 - z2).cwiseAbs().maxCoeff(), 0.0);
  // Rows of fixed particles are decoupled (identity) in the factor; compare
  // on the free rows.
  MatrixN3 residual = sm.matrix() * z2 - x;
  for (int p : sys.fixed()) residual.row(p).setZero();
  EXPECT_LT(residual.norm(), 1e-9 * x.norm());
}

// The parallel force path (≥ 20 000 centres and springs, buffer + gather):
// the internal forces of a large sheet still sum to zero to round-off
// (momentum, as the small-sheet test checks for the serial path); a missing,
// misplaced or doubled buffer entry would leave an O(1) residue. Round-off:
// 30 000 particles × ~10 terms of relative 1e-16 each ≪ 1e-10.
TEST(ParallelKernels, InternalForcesSumToZero) {
  const ParticleSystem sys(testing::InternalForcesScene(200, 150));
  MatrixN3 x, v, g(sys.num_particles(), 3);
  testing::PerturbedState(sys, 11, &x, &v);
  sys.ExplicitForces(0.0, x, v, &g);
  const double scale = g.cwiseAbs().sum();
  ASSERT_GT(scale, 0.0);
  EXPECT_LT(g.colwise().sum().norm(), 1e-10 * scale);
}

}  // namespace
}  // namespace clothbench
