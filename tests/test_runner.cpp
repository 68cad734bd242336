// The scenario runner: undo/redo and live frames return exactly to states a fresh run reaches,
// front-end options win over the scenario's, the saved scenario replays what was done, and the
// report carries read and write times. References are fresh runners doing the plain thing.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/io/io.h"
#include "support/shapes.h"
#include "test_util.h"

namespace {

hgd::Scenario barScenario() {
  hgd::Scenario s;
  s.fix(hgd::Region::box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0.1, 1, 1)))
      .manipulate(hgd::Region::box(Eigen::Vector3d(0.9, -1, -1), Eigen::Vector3d(2, 1, 1)));
  return s;
}

hgd::Move dragMove(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  hgd::Move m;
  m.kind = hgd::Move::Kind::Drag;
  m.drag.from = from;
  m.drag.to = to;
  return m;
}

hgd::Move turnMove(double degrees) {
  hgd::Move m;
  m.kind = hgd::Move::Kind::Frame;
  m.frame.axis = Eigen::Vector3d::UnitY();
  m.frame.degrees = degrees;
  return m;
}

double largestDifference(const hgd::ScenarioRunner& a, const hgd::ScenarioRunner& b) {
  const auto &pa = a.deformer().deformedPoints(), &pb = b.deformer().deformedPoints();
  EXPECT_EQ(pa.size(), pb.size());
  double worst = 0;
  for (std::size_t i = 0; i < pa.size() && i < pb.size(); ++i)
    worst = std::max(worst, static_cast<double>((pa[i] - pb[i]).norm()));
  return worst;
}

hgd::ScenarioRunner bar(const hgd::Scenario& s = barScenario(), const hgd::RunOptions& o = {}) {
  hgd::ScenarioRunner run(hgd::shapes::bar(1.0f, 0.1f, 0.01f), o);
  run.setScenario(s);
  return run;
}

const Eigen::Vector3d kTip(1.0, 0.05, 0.0);

TEST(ScenarioRunner, UndoAndRedoReturnToTheStatesAFreshRunReaches) {
  const hgd::Move m1 = dragMove(kTip, kTip + Eigen::Vector3d(0, 0, 0.3)), m2 = turnMove(40);
  hgd::ScenarioRunner a = bar();
  a.apply(m1);
  a.apply(m2);
  const std::vector<Eigen::Vector3f> both = a.deformer().deformedPoints();
  ASSERT_TRUE(a.undo());
  hgd::ScenarioRunner one = bar();
  one.apply(m1);
  EXPECT_EQ(a.moves().size(), 1u);
  const double after_undo = largestDifference(a, one);
  ASSERT_TRUE(a.redo());
  double after_redo = 0;
  for (std::size_t i = 0; i < both.size(); ++i)
    after_redo =
        std::max(after_redo, static_cast<double>((a.deformer().deformedPoints()[i] - both[i]).norm()));
  // The moves did something: the two states are far apart.
  const double apart = largestDifference(a, one);
  std::printf("undo vs one move: %.3g; redo vs both moves: %.3g; the two states differ by %.3g\n", after_undo,
              after_redo, apart);
  EXPECT_LE(after_undo, 1e-6);
  EXPECT_LE(after_redo, 1e-6);
  EXPECT_GT(apart, 0.1);
  EXPECT_FALSE(a.redo());
  ASSERT_TRUE(a.undo());
  ASSERT_TRUE(a.undo());
  EXPECT_FALSE(a.undo());
  // At rest again: every point where it was read.
  double rest = 0;
  for (std::size_t i = 0; i < a.geometry().size(); ++i)
    rest = std::max(
        rest, static_cast<double>(
                  (a.deformer().deformedPoints()[i] - a.geometry().points->at(i).getVector3fMap()).norm()));
  EXPECT_LE(rest, 1e-6);
  // The report counts only the moves that stand.
  EXPECT_EQ(a.report().frames, 0);
}

TEST(ScenarioRunner, LiveFramesAreDroppedWhenAMoveIsApplied) {
  const hgd::Move m = dragMove(kTip, kTip + Eigen::Vector3d(0, 0.2, 0.2));
  hgd::ScenarioRunner a = bar();
  for (int k = 1; k <= 10; ++k) a.liveDrag(kTip, kTip + Eigen::Vector3d(0, 0, -0.03 * k));
  a.apply(m);
  hgd::ScenarioRunner b = bar();
  b.apply(m);
  const double d = largestDifference(a, b);
  std::printf("live frames then a move vs the move alone: %.3g\n", d);
  EXPECT_LE(d, 1e-6);
  // Undo after live frames goes back to before the last applied move, not to a live frame.
  for (int k = 1; k <= 5; ++k) a.liveDrag(kTip, kTip + Eigen::Vector3d(0, -0.05 * k, 0));
  ASSERT_TRUE(a.undo());
  EXPECT_TRUE(a.moves().empty());
}

// The viewer's level of detail: live frames interpolate a subset (every 7th point). Those
// points must be where the full interpolation puts them, to the bit (their own rows of the
// table); the others must not have been computed (the subset is the saving); and leaving the
// live frames, by a committed move, must give every point exactly as without a preview.
TEST(ScenarioRunner, PreviewFramesInterpolateTheirPointsExactly) {
  hgd::ScenarioRunner a = bar(), b = bar();
  std::vector<int> subset;
  for (std::size_t i = 0; i < a.geometry().size(); i += 7) subset.push_back(static_cast<int>(i));
  const std::vector<Eigen::Vector3f> rest = a.deformer().deformedPoints();
  for (int k = 1; k <= 4; ++k) {
    const Eigen::Vector3d to = kTip + Eigen::Vector3d(0, 0.05 * k, 0.03 * k);
    a.liveDrag(kTip, to, false, &subset);
    b.liveDrag(kTip, to);
  }
  // The subset and the dragged handle's points (picking reads those).
  const std::vector<int>& drawn = a.deformer().preview();
  std::vector<char> in(a.geometry().size(), 0);
  for (const int i : drawn) in[static_cast<std::size_t>(i)] = 1;
  for (const int i : subset) EXPECT_TRUE(in[static_cast<std::size_t>(i)]);
  for (const int i : a.handles().manipulated) EXPECT_TRUE(in[static_cast<std::size_t>(i)]);
  const auto &pa = a.deformer().deformedPoints(), &pb = b.deformer().deformedPoints();
  std::size_t same = 0, behind = 0;
  for (std::size_t i = 0; i < pa.size(); ++i) {
    if (in[i])
      same += pa[i] == pb[i];
    else
      behind += pa[i] == rest[i] && pb[i] != rest[i];
  }
  EXPECT_EQ(same, drawn.size());
  EXPECT_GT(behind, pa.size() / 2);  // the rest were left as they were (the drag moved them in b)
  const hgd::Move m = dragMove(kTip, kTip + Eigen::Vector3d(0, 0.2, 0.12));
  a.apply(m);
  b.apply(m);
  EXPECT_TRUE(a.deformer().preview().empty());
  EXPECT_EQ(largestDifference(a, b), 0.0);
}

// A move turns positions only; normals are derived when asked for. Each point's normal must
// still come from the transforms its position came from: across preview frames the others keep
// the last full frame's, the preview's points get the current ones (b reads after every frame).
TEST(ScenarioRunner, NormalsMatchTheirPointsAcrossPreviewFrames) {
  hgd::ScenarioRunner a = bar(), b = bar();
  ASSERT_TRUE(a.deformer().interpolationTable().has_normals);
  const std::size_t n = a.geometry().size();
  std::vector<int> every7, others7;
  for (std::size_t i = 0; i < n; i += 7) every7.push_back(static_cast<int>(i));
  for (std::size_t i = 3; i < n; i += 7) others7.push_back(static_cast<int>(i));
  const Eigen::Vector3d first = kTip + Eigen::Vector3d(0, 0.1, 0.05);
  a.apply(dragMove(kTip, first));  // a full frame whose normals a never reads
  b.apply(dragMove(kTip, first));
  // Which of b's frames each point of a should show: 0 the full frame, then one per live frame
  // (a and b make the same solves; b reads its normals after each).
  std::vector<int> expect(n, 0);
  std::vector<std::vector<Eigen::Vector3f>> seen{b.deformer().deformedNormals()};
  auto frame = [&](const Eigen::Vector3d& to, const std::vector<int>* subset) {
    a.liveDrag(first, to, false, subset);
    b.liveDrag(first, to);
    seen.push_back(b.deformer().deformedNormals());
    for (const int i : a.deformer().preview())
      expect[static_cast<std::size_t>(i)] = static_cast<int>(seen.size()) - 1;
  };
  for (int k = 1; k <= 4; ++k) {
    const Eigen::Vector3d to = first + Eigen::Vector3d(0, 0.05 * k, 0.03 * k);
    frame(to, &every7);
    if (k == 3) a.deformer().setPreview(others7);  // another subset, mid-drag
    if (k >= 3) frame(to, nullptr);                // and a frame with it
  }
  const auto& na = a.deformer().deformedNormals();
  std::size_t right = 0, turned = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& want = seen[static_cast<std::size_t>(expect[i])][i];
    right += na[i] == want;
    turned += (seen.back()[i] - want).norm() > 1e-4f;
  }
  EXPECT_EQ(right, n);
  EXPECT_GT(turned, n / 2);  // so that a normal of the wrong frame would show
  // Leaving the preview: every normal is the current one again.
  const hgd::Move m = dragMove(kTip, kTip + Eigen::Vector3d(0, 0.2, 0.12));
  a.apply(m);
  b.apply(m);
  const auto &ma = a.deformer().deformedNormals(), &mb = b.deformer().deformedNormals();
  std::size_t differ = 0;
  for (std::size_t i = 0; i < ma.size(); ++i) differ += ma[i] != mb[i];
  EXPECT_EQ(differ, 0u);
}

TEST(ScenarioRunner, FrontEndOptionsWinOverTheScenario) {
  hgd::Scenario s = barScenario();
  s.clusters = 5;
  s.blend = hgd::Blend::Linear;
  const hgd::Move turn = turnMove(120);
  s.moves = {turn};
  EXPECT_EQ(bar(s).report().isovalues, 5);
  hgd::RunOptions o;
  o.clusters = 9;
  o.blend = hgd::Blend::Rotation;
  hgd::ScenarioRunner a = bar(s, o);
  EXPECT_EQ(a.report().isovalues, 9);
  a.applyMoves();
  // The same as a scenario that says 9 and rotation itself.
  hgd::Scenario t = barScenario();
  t.clusters = 9;
  t.blend = hgd::Blend::Rotation;
  hgd::ScenarioRunner b = bar(t);
  b.apply(turn);
  hgd::ScenarioRunner linear = bar(s);
  linear.applyMoves();
  const double same = largestDifference(a, b), other = largestDifference(a, linear);
  std::printf("options vs the same in the scenario: %.3g; vs the scenario's own: %.3g\n", same, other);
  EXPECT_LE(same, 1e-6);
  EXPECT_GT(other, 1e-3);
  // The scenario a front end saves says what was used.
  EXPECT_EQ(a.scenario().clusters, 9);
  EXPECT_EQ(a.scenario().blend, hgd::Blend::Rotation);
}

// A second scenario with another isovalue count or resolution builds a new deformer (the
// session's rule, shared with the PCL stage and Python): the runner's result is a fresh
// runner's, bit for bit. A runner that kept the first deformer would keep its clusters.
TEST(ScenarioRunner, ASecondScenarioWithOtherClustersIsBuiltAsAFreshOne) {
  hgd::Scenario s9 = barScenario(), s4 = barScenario();
  s9.clusters = 9;
  s4.clusters = 4;
  s9.moves = s4.moves = {turnMove(60)};
  hgd::ScenarioRunner used = bar(s9);
  used.applyMoves();
  const std::size_t clusters9 = used.deformer().clustering().clusters.size();
  used.setScenario(s4);
  used.applyMoves();
  hgd::ScenarioRunner fresh = bar(s4);
  fresh.applyMoves();
  std::printf("clusters: %zu at 9 isovalues, %zu at 4 (fresh %zu)\n", clusters9,
              used.deformer().clustering().clusters.size(), fresh.deformer().clustering().clusters.size());
  EXPECT_LT(used.deformer().clustering().clusters.size(), clusters9);
  EXPECT_EQ(used.deformer().clustering().clusters.size(), fresh.deformer().clustering().clusters.size());
  EXPECT_EQ(largestDifference(used, fresh), 0.0);
  EXPECT_EQ(used.report().isovalues, 4);
  EXPECT_EQ(used.moves().size(), 1u);  // the first scenario's move went with its build

  // Full resolution asked by the second scenario: every point in the graph, as fresh.
  hgd::Scenario full = s4;
  full.full_resolution = true;
  hgd::RunOptions coarse;
  coarse.deform.multires_above = 1;  // this small bar on a coarse level, as the test below
  coarse.deform.coarse_points = 500;
  coarse.deform.points_per_coarse = 0;
  hgd::ScenarioRunner a = bar(s4, coarse);
  ASSERT_TRUE(a.deformer().coarseLevel().points.size() > 0);
  a.setScenario(full);
  EXPECT_EQ(a.deformer().coarseLevel().points.size(), 0u);
  a.applyMoves();
  hgd::ScenarioRunner b = bar(full, coarse);
  b.applyMoves();
  EXPECT_EQ(largestDifference(a, b), 0.0);
}

// What a failed or emptying change leaves: a scenario whose region fits no point throws and the
// runner keeps its deformer, moves and undo; emptying the handles during live frames does not
// throw and marking them again builds what a fresh runner builds; a session whose handles were
// given as indices falls back to the saved regions on a new shape.
TEST(ScenarioRunner, FailedAndEmptyingChangesKeepTheRunnerConsistent) {
  hgd::ScenarioRunner run = bar();
  run.apply(turnMove(40));
  const std::vector<Eigen::Vector3f> turned = run.deformer().deformedPoints();
  hgd::Scenario off = barScenario();
  off.manipulate(hgd::Region::box(Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6)));  // no point
  EXPECT_THROW(run.setScenario(off), hgd::ScenarioError);
  ASSERT_TRUE(run.ready());
  EXPECT_EQ(run.moves().size(), 1u);
  EXPECT_TRUE(run.deformer().deformedPoints() == turned);
  EXPECT_TRUE(run.undo());
  EXPECT_TRUE(run.deformer().deformedPoints() == bar().deformer().deformedPoints());

  const hgd::Handles handles = run.handles();
  run.liveDrag(kTip, kTip + Eigen::Vector3d(0, 0.1, 0));
  EXPECT_NO_THROW(run.setHandles(hgd::Handles{}));
  EXPECT_FALSE(run.ready());
  run.setHandles(handles);
  ASSERT_TRUE(run.ready());
  EXPECT_TRUE(run.undo() == false);  // the history went with the handles
  run.apply(turnMove(30));
  hgd::ScenarioRunner fresh = bar();
  fresh.apply(turnMove(30));
  EXPECT_EQ(largestDifference(run, fresh), 0.0);

  hgd::Session session(hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  session.setHandles(handles);
  const hgd::Scenario regions = barScenario();
  session.setRegions(regions.fixed, regions.manipulated, regions.joints);
  ASSERT_TRUE(session.ensureBuilt());
  session.setShape(hgd::shapes::bar(2.0f, 0.1f, 0.01f));  // twice as long: other indices
  EXPECT_TRUE(session.missingHandle().empty());
  ASSERT_TRUE(session.ensureBuilt());
  hgd::ScenarioRunner longer(hgd::shapes::bar(2.0f, 0.1f, 0.01f));
  longer.setScenario(regions);
  EXPECT_EQ(session.handles().fixed, longer.handles().fixed);
  EXPECT_EQ(session.handles().manipulated, longer.handles().manipulated);
}

// "resolution": "full" reaches the Deformer from the scenario (every front end reads one), is
// saved back, and a bad value is refused with its path.
TEST(ScenarioRunner, ResolutionKeyKeepsEveryPointInTheField) {
  hgd::RunOptions o;
  o.deform.multires_above = 1;  // this small bar would be built on a coarse level
  o.deform.coarse_points = 500;
  o.deform.points_per_coarse = 0;
  EXPECT_FALSE(bar(barScenario(), o).deformer().coarseLevel().empty());
  hgd::Scenario s = barScenario();
  s.full_resolution = true;
  hgd::ScenarioRunner full = bar(s, o);
  EXPECT_TRUE(full.deformer().coarseLevel().empty());
  const hgd::Scenario saved = hgd::parseScenario(hgd::scenarioToJson(full.scenario()), "saved.json");
  EXPECT_EQ(saved.full_resolution, std::optional<bool>(true));
  EXPECT_TRUE(bar(saved, o).deformer().coarseLevel().empty());
  try {
    hgd::parseScenario(R"({"fixed": [{"sphere": {"center": [0, 0, 0], "radius": 1}}],
      "manipulated": {"sphere": {"center": [1, 0, 0], "radius": 0.1}}, "resolution": "half"})",
                       "s.json");
    ADD_FAILURE() << "accepted \"half\"";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(R"(s.json: /resolution: must be "auto" or "full")"),
              std::string::npos)
        << e.what();
  }
}

// `hgdeform field` goes through ScenarioRunner::field(): the field a full-resolution deformer
// builds, value for value, and the runner itself left as it was (no deformer built, even for a
// shape the deformer would build on a coarse level).
TEST(ScenarioRunner, FieldAloneIsTheFullResolutionDeformersField) {
  hgd::RunOptions o;
  o.deform.multires_above = 1;  // a deformer of this bar would be built on a coarse level...
  o.deform.coarse_points = 500;
  o.deform.points_per_coarse = 0;
  hgd::ScenarioRunner alone(hgd::shapes::bar(1.0f, 0.1f, 0.01f), o);
  const hgd::FieldResult f = alone.field(barScenario());
  EXPECT_FALSE(alone.ready());
  hgd::Scenario s = barScenario();
  s.full_resolution = true;  // ...the field alone is the full resolution's
  const hgd::ScenarioRunner full = bar(s, o);
  ASSERT_EQ(f.values.size(), full.geometry().size());
  EXPECT_EQ(f.values, full.deformer().field());
  EXPECT_EQ(f.handles.manipulated, full.handles().manipulated);
  EXPECT_EQ(f.handles.fixed, full.handles().fixed);
  EXPECT_EQ(f.unreachable, full.deformer().unreachablePoints());
  EXPECT_GT(f.timings.total(), 0.0);
}

TEST(ScenarioRunner, TheSavedScenarioReplaysWhatWasDone) {
  hgd::ScenarioRunner a = bar();
  a.apply(dragMove(kTip, kTip + Eigen::Vector3d(0, 0, 0.25)));
  a.apply(turnMove(-30));
  a.apply(dragMove(kTip, kTip + Eigen::Vector3d(0.1, 0, 0)));
  a.undo();
  const hgd::Scenario saved = hgd::parseScenario(hgd::scenarioToJson(a.scenario()), "saved.json");
  ASSERT_EQ(saved.moves.size(), 2u);
  hgd::ScenarioRunner b = bar(saved);
  b.applyMoves();
  const double d = largestDifference(a, b);
  std::printf("saved scenario replayed vs the session: %.3g\n", d);
  EXPECT_LE(d, 1e-5);  // JSON keeps 17 significant digits; measured 0
}

TEST(ScenarioRunner, ReportsReadAndWriteTimesAndNeverWritesOverItsInput) {
  hgdtest::TempDir dir;
  const std::string in = (dir.path() / "bar.ply").string(), out = (dir.path() / "out.pcd").string();
  hgd::writeShape(in, hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  const std::string before = hgdtest::slurp(in);
  hgd::ScenarioRunner run = hgd::ScenarioRunner::read(in);
  run.setScenario(barScenario());
  run.apply(dragMove(kTip, kTip + Eigen::Vector3d(0, 0, 0.2)));
  EXPECT_THROW(run.write(in), hgd::IoError);
  EXPECT_EQ(hgdtest::slurp(in), before);
  run.write(out);
  const hgd::DeformReport rep = run.report();
  EXPECT_GT(rep.read_ms, 0.0);
  EXPECT_GT(rep.write_ms, 0.0);
  EXPECT_GE(rep.build_ms, rep.read_ms);
  EXPECT_GE(rep.total_ms, rep.build_ms + rep.solve_ms + rep.write_ms - 1e-9);
  // What was written is the deformed shape.
  const hgd::Geometry g = hgd::extractGeometry(hgd::readShape(out));
  double tip = 0;
  for (std::size_t i = 0; i < g.size(); ++i) tip = std::max(tip, g.world(i).z());
  EXPECT_GT(tip, 0.15);
}

// writeAndRelease (the one-shot commands' write: the runner's own shape deformed in place, not a
// copy) refuses its input like write(), and then writes the same bytes write() writes.
TEST(ScenarioRunner, WriteAndReleaseWritesWhatWriteWrites) {
  hgdtest::TempDir dir;
  const std::string in = dir.file("bar.ply"), a = dir.file("a.ply"), b = dir.file("b.ply");
  hgd::writeShape(in, hgd::shapes::bar(1.0f, 0.1f, 0.01f));
  const std::string before = hgdtest::slurp(in);
  auto run = [&] {
    hgd::ScenarioRunner r = hgd::ScenarioRunner::read(in);
    r.setScenario(barScenario());
    r.apply(dragMove(kTip, kTip + Eigen::Vector3d(0, 0, 0.2)));
    return r;
  };
  hgd::ScenarioRunner ra = run(), rb = run();
  ra.write(a);
  // Refused before the write began: the runner keeps its shape and can still write it.
  EXPECT_THROW(rb.writeAndRelease(in), hgd::IoError);
  EXPECT_EQ(hgdtest::slurp(in), before);
  rb.writeAndRelease(b);
  EXPECT_EQ(hgdtest::slurp(a), hgdtest::slurp(b));
  EXPECT_NE(hgdtest::slurp(b), before);
  const hgd::DeformReport ka = ra.report(), kb = rb.report();
  EXPECT_GT(kb.write_ms, 0.0);
  EXPECT_EQ(kb.points, ka.points);
  EXPECT_EQ(kb.clusters, ka.clusters);
  EXPECT_EQ(kb.surface.max_stretch, ka.surface.max_stretch);
  // The shape is gone: what needs it says so instead of reading an empty shape.
  EXPECT_THROW(rb.write(dir.file("c.ply")), std::logic_error);
  EXPECT_THROW(rb.deformedShape(), std::logic_error);
  EXPECT_THROW(rb.apply(dragMove(kTip, kTip)), std::logic_error);
  EXPECT_FALSE(std::filesystem::exists(dir.file("c.ply")));
}

}  // namespace

namespace {

// The rotation part of the best rigid fit of the handle's points, rest -> deformed, in degrees
// (Kabsch, computed here).
double handleTurnDegrees(const hgd::ScenarioRunner& run) {
  const hgd::Deformer& d = run.deformer();
  const auto& idx = d.handles().manipulated;
  Eigen::Vector3d c0 = Eigen::Vector3d::Zero(), c1 = Eigen::Vector3d::Zero();
  for (int i : idx) {
    c0 += d.geometry().world(static_cast<std::size_t>(i));
    c1 += d.deformedWorld(static_cast<std::size_t>(i));
  }
  c0 /= static_cast<double>(idx.size());
  c1 /= static_cast<double>(idx.size());
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i : idx)
    h += (d.geometry().world(static_cast<std::size_t>(i)) - c0) *
         (d.deformedWorld(static_cast<std::size_t>(i)) - c1).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixV() * svd.matrixU().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d v = svd.matrixV();
    v.col(2) *= -1;
    r = v * svd.matrixU().transpose();
  }
  return Eigen::AngleAxisd(r).angle() * 180.0 / M_PI;
}

}  // namespace

// A drag with keep_orientation: the handle translates without turning, its picked point (the
// handle point nearest `from`, found here) lands on `to`, every handle point moves by the same
// vector; the paper's drag turns the same handle (measured: 24 degrees). The saved scenario
// keeps the key, and replays to the same shape.
TEST(ScenarioRunner, DragKeepingOrientationTranslatesTheHandle) {
  const Eigen::Vector3d from = kTip, to = kTip + Eigen::Vector3d(0, 0.35, 0.2);
  hgd::Move keep = dragMove(from, to);
  keep.drag.keep_orientation = true;
  hgd::ScenarioRunner a = bar();
  const hgd::MoveResult r = a.apply(keep);
  EXPECT_TRUE(r.reached);
  const hgd::Deformer& d = a.deformer();
  int picked = -1;
  double best = INFINITY;
  for (int i : d.handles().manipulated)
    if ((d.geometry().world(static_cast<std::size_t>(i)) - from).norm() < best) {
      best = (d.geometry().world(static_cast<std::size_t>(i)) - from).norm();
      picked = i;
    }
  const Eigen::Vector3d shift = to - d.geometry().world(static_cast<std::size_t>(picked));
  double off = 0;
  for (int i : d.handles().manipulated) {
    const auto u = static_cast<std::size_t>(i);
    off = std::max(off, (d.deformedWorld(u) - d.geometry().world(u) - shift).norm());
  }
  hgd::ScenarioRunner b = bar();
  b.apply(dragMove(from, to));
  const double turned_keep = handleTurnDegrees(a), turned_paper = handleTurnDegrees(b);
  std::printf(
      "keep_orientation: handle off the translation by %.2e, turned %.3f deg; the paper's drag: %.1f deg\n",
      off, turned_keep, turned_paper);
  EXPECT_LE(off, 1e-5);           // float positions of a bar of length 1
  EXPECT_LE(turned_keep, 1e-3);   // measured: 0
  EXPECT_GE(turned_paper, 10.0);  // the difference the key makes
  EXPECT_GE(largestDifference(a, b), 0.05);

  const hgd::Scenario saved = a.scenario();
  ASSERT_EQ(saved.moves.size(), 1u);
  EXPECT_TRUE(saved.moves[0].drag.keep_orientation);
  const std::string json = hgd::scenarioToJson(saved);
  EXPECT_NE(json.find("\"keep_orientation\": true"), std::string::npos) << json;
  hgd::ScenarioRunner c = bar();
  c.setScenario(hgd::parseScenario(json, "saved.json"));
  c.applyMoves();
  EXPECT_EQ(largestDifference(a, c), 0.0);
}

// keep_orientation is a boolean, with the parser's JSON-path error otherwise.
TEST(ScenarioRunner, KeepOrientationMustBeABoolean) {
  try {
    hgd::parseScenario(R"({"fixed": [{"sphere": {"center": [0, 0, 0], "radius": 1}}],
      "manipulated": {"sphere": {"center": [1, 0, 0], "radius": 0.1}},
      "move": {"drag": {"from": [1, 0, 0], "to": [1, 1, 0], "keep_orientation": 1}}})",
                       "s.json");
    ADD_FAILURE() << "accepted a number";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("s.json: /move/drag/keep_orientation: must be true or false"),
              std::string::npos)
        << e.what();
  }
}

namespace {

// What the viewer's live drag frames are (issue 29, item 1): previewMove() shows the move's own
// result, from the last applied state, however many previews came before (the cursor's path
// does not matter); commitLive() keeps it, to the bit, without solving again; it equals apply()
// of the same move on a fresh runner, and with a level of detail every point is there after the
// commit.
TEST(ScenarioRunner, PreviewedMoveIsCommittedAsShown) {
  const Eigen::Vector3d to = kTip + Eigen::Vector3d(-0.2, 0.4, 0.1);
  hgd::ScenarioRunner a = bar(), b = bar(), c = bar();
  std::vector<int> subset;
  for (std::size_t i = 0; i < a.geometry().size(); i += 5) subset.push_back(static_cast<int>(i));
  for (int k = 1; k <= 6; ++k)  // a wandering path, ending at `to`
    a.previewMove(dragMove(kTip, kTip + Eigen::Vector3d(0.05 * k, -0.1 * k, 0)), &subset);
  a.previewMove(dragMove(kTip, to), &subset);
  const std::vector<Eigen::Vector3f> shown = a.deformer().deformedPoints();
  ASSERT_TRUE(a.commitLive().has_value());
  ASSERT_EQ(a.moves().size(), 1u);
  EXPECT_FALSE(a.commitLive().has_value());  // nothing live any more
  const auto& kept = a.deformer().deformedPoints();
  for (const int i : subset)
    EXPECT_EQ(shown[static_cast<std::size_t>(i)], kept[static_cast<std::size_t>(i)]) << i;
  b.apply(dragMove(kTip, to));
  EXPECT_EQ(largestDifference(a, b), 0.0);
  // Undo returns to before the gesture; a live frame of incremental drags is not committable.
  ASSERT_TRUE(a.undo());
  EXPECT_LE(largestDifference(a, c), 1e-7);
  a.liveDrag(kTip, to);
  EXPECT_FALSE(a.commitLive().has_value());
}

}  // namespace
