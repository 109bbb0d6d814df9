// State files (core/state_file.hpp, docs/file_format.md): every class round-trips bit for bit,
// a loaded object continues exactly as the saved one, and damaged files are refused by name.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "probslam/core/check.hpp"
#include "probslam/core/options_description.hpp"
#include "probslam/core/pose2.hpp"
#include "probslam/core/range_bearing_model.hpp"
#include "probslam/core/state_file.hpp"
#include "probslam/ekf/ekf_slam.hpp"
#include "probslam/ekf/multi_hypothesis_ekf_slam.hpp"
#include "probslam/fastslam/fast_slam.hpp"
#include "probslam/fastslam/grid_fast_slam.hpp"
#include "probslam/graph/pose_graph_2d.hpp"
#include "probslam/graph/pose_graph_3d.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/grid/occupancy_grid_3d.hpp"
#include "probslam/localization/monte_carlo_localization.hpp"
#include "probslam/slam2d/submap_slam.hpp"
#include "test_support.hpp"

namespace probslam {
namespace {

using test_support::cast;
using test_support::room_walls;

std::string temp_path(const std::string& name) { return ::testing::TempDir() + "probslam_state_" + name; }

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// A refused load: std::invalid_argument whose message starts with the path and contains `what`.
template <typename T>
void expect_refused(const std::string& path, const std::string& what) {
  try {
    T::load(path);
    ADD_FAILURE() << "loaded a damaged " << T::kStateTag << " (" << what << ")";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path, 0), 0u) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
}

// Saves obj, loads it back: the loaded state's bytes equal the saved ones; then truncated,
// damaged, wrong-class and wrong-version files are refused and obj is unchanged.
template <typename T, typename Other>
T round_trip(const T& obj, const std::string& name) {
  const std::string path = temp_path(name);
  const std::string before = state_bytes(obj);
  obj.save(path);
  EXPECT_EQ(read_bytes(path), before);
  T loaded = T::load(path);
  EXPECT_EQ(state_bytes(loaded), before);

  const std::string bad = temp_path(name + "_bad");
  for (std::size_t cut : {std::size_t{0}, std::size_t{5}, std::size_t{30}, before.size() / 2, before.size() - 1}) {
    write_bytes(bad, before.substr(0, cut));
    expect_refused<T>(bad, cut < 8 ? "not a probslam state file" : "truncated");
  }
  std::string flipped = before;
  flipped[flipped.size() - 3] ^= 0x10;
  write_bytes(bad, flipped);
  expect_refused<T>(bad, "checksum");
  write_bytes(bad, before + "x");
  expect_refused<T>(bad, "padded");
  std::string version = before;
  constexpr std::uint32_t kOtherVersion = kStateFormatVersion + 1;  // any version but this build's
  version[8] = static_cast<char>(kOtherVersion);
  write_bytes(bad, version);
  expect_refused<T>(bad, "version " + std::to_string(kOtherVersion));
  // A file of another class names both.
  write_bytes(bad, frame_state(Other::kStateTag, ""));
  expect_refused<T>(bad, std::string("holds a ") + Other::kStateTag);
  EXPECT_THROW(T::load(temp_path(name + "_missing")), FileNotFound);
  EXPECT_EQ(state_bytes(obj), before);
  std::remove(path.c_str());
  std::remove(bad.c_str());
  return loaded;
}

// A corrupt length inside a valid frame (the checksum recomputed) is refused before allocation.
// A described options struct of every field kind, for the generic state layout.
enum class Shade { kLight, kDark };
}  // namespace
template <>
struct OptionEnum<Shade> {
  static constexpr std::array<const char*, 2> names{"light", "dark"};
};
namespace {
struct Inner {
  double a = 1.5;
  int b = -3;
  template <class V>
  static void describe(V& v) {
    v("a", &Inner::a, "m", "a length");
    v("b", &Inner::b, "", "a count");
  }
};
struct Outer {
  Shade shade = Shade::kDark;
  Inner inner;
  std::uint64_t seed = 7;
  bool flag = true;
  template <class V>
  static void describe(V& v) {
    v("shade", &Outer::shade, "", "an enum");
    v("inner", &Outer::inner, "", "a group");
    v("seed", &Outer::seed, "", "a seed");
    v("flag", &Outer::flag, "", "a flag");
  }
};

TEST(StateFile, DescribedOptionsAreTheirFieldsInOrderGroupsInline) {
  Outer o;
  o.inner.a = -2.25;
  o.seed = 1ULL << 60;
  StateWriter w;
  write_options(w, o);
  // By hand: the enum's byte, the group's double and int, the seed, the flag.
  StateWriter expected;
  expected.u8(1);
  expected.f64(-2.25);
  expected.i32(-3);
  expected.u64(1ULL << 60);
  expected.boolean(true);
  ASSERT_EQ(w.payload(), expected.payload());
  StateReader r(w.payload().data(), w.payload().size(), "state");
  Outer back;
  back.shade = Shade::kLight;
  back.flag = false;
  read_options(r, back);
  EXPECT_EQ(back.shade, Shade::kDark);
  EXPECT_EQ(back.inner.a, -2.25);
  EXPECT_EQ(back.inner.b, -3);
  EXPECT_EQ(back.seed, 1ULL << 60);
  EXPECT_TRUE(back.flag);
  // An enum value beyond its names is refused, naming the field.
  std::string bad = w.payload();
  bad[0] = 2;
  StateReader rb(bad.data(), bad.size(), "state");
  try {
    read_options(rb, back);
    FAIL() << "an unknown enum value was read";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("shade holds an unknown value 2"), std::string::npos) << e.what();
  }
}

TEST(StateFile, CorruptLengthIsCheckedAgainstTheBytesLeft) {
  StateWriter w;
  w.count(std::size_t{1} << 60);  // a vector of 2^60 doubles, none present
  const std::string framed = frame_state("PoseGraph2D", w.payload());
  EXPECT_THROW(object_from_state<PoseGraph2D>(framed, "state"), StateError);
  StateReader r(w.payload().data(), w.payload().size(), "state");
  try {
    r.doubles();
    FAIL();
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("exceeds the 0 bytes left"), std::string::npos) << e.what();
  }
  // A matrix whose dimensions claim more than is there.
  StateWriter m;
  m.i64(1 << 20);
  m.i64(1 << 20);
  StateReader rm(m.payload().data(), m.payload().size(), "state");
  EXPECT_THROW(rm.matrix<Eigen::MatrixXd>(), StateError);
}

// A dynamic dimension is a count even when the other is zero: an empty 0 x 2^62 matrix is
// refused at once (it was read as 2^62 empty columns, a loop that never ended), as is a product
// that overflows. Fixed dimensions are the type's: a 3 x 0 block with no bytes left is read.
TEST(StateFile, EmptyMatrixDimensionsAreCounts) {
  for (const auto& [rows, cols] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {0, std::int64_t{1} << 62}, {std::int64_t{1} << 62, 0}, {std::int64_t{1} << 33, std::int64_t{1} << 33}}) {
    StateWriter w;
    w.i64(rows);
    w.i64(cols);
    for (int k = 0; k < 8; ++k) w.f64(1.0);
    StateReader r(w.payload().data(), w.payload().size(), "state");
    try {
      r.matrix<Eigen::MatrixXd>();
      ADD_FAILURE() << rows << " x " << cols << " read";
    } catch (const StateError& e) {
      EXPECT_NE(std::string(e.what()).find("bytes left"), std::string::npos) << e.what();
    }
  }
  StateWriter w;
  w.i64(3);
  w.i64(0);
  StateReader r(w.payload().data(), w.payload().size(), "state");
  using ThreeRows = Eigen::Matrix<double, 3, Eigen::Dynamic>;
  EXPECT_EQ(r.matrix<ThreeRows>().cols(), 0);
}

TEST(StateFile, OccupancyGrid2D) {
  OccupancyGrid2D g(0.1, 40, 30, {-2.0, -1.5}, 0.4, LogOddsClamp::none());
  g.set_beam_model({0.8, 0.3});
  Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(90, -1.5, 1.5);
  g.insert_rays({0.1, 0.2, 0.3}, Eigen::VectorXd::Constant(90, 1.2), angles, 3.0);
  OccupancyGrid2D h = round_trip<OccupancyGrid2D, PoseGraph2D>(g, "grid");
  EXPECT_TRUE(h.same_geometry(g));
  EXPECT_EQ(h.p_prior(), g.p_prior());
  EXPECT_EQ(h.clamp().enabled, false);
  EXPECT_EQ(h.beam_model().p_hit, 0.8);
  EXPECT_TRUE((h.log_odds().array() == g.log_odds().array()).all());
  // Both continue alike: the reset scan stamps keep their meaning.
  g.insert_rays({0.5, 0.1, -0.2}, Eigen::VectorXd::Constant(90, 0.9), angles, 3.0);
  h.insert_rays({0.5, 0.1, -0.2}, Eigen::VectorXd::Constant(90, 0.9), angles, 3.0);
  EXPECT_TRUE((h.log_odds().array() == g.log_odds().array()).all());
}

TEST(StateFile, PoseGraph2D) {
  PoseGraph2D g;
  g.add_pose(3, {0, 0, 0});
  g.add_pose(7, {1, 0.1, 0.2});
  g.add_point(9, {2, 1}, 42);
  g.set_fixed(3);
  g.add_pose_edge(3, 7, {1, 0, 0.2}, Eigen::Matrix3d::Identity() * 4);
  g.add_point_edge(7, 9, {1, 1}, Eigen::Matrix2d::Identity());
  g.vertex(1).value[2] = 4.0;  // an optimiser's unwrapped angle survives as it is
  const PoseGraph2D h = round_trip<PoseGraph2D, OccupancyGrid2D>(g, "graph");
  ASSERT_EQ(h.num_vertices(), 3);
  EXPECT_EQ(h.vertex(1).value[2], 4.0);
  EXPECT_TRUE(h.vertex(0).fixed);
  EXPECT_EQ(h.vertex(2).landmark_id, 42);
  EXPECT_EQ(h.index_of(9), 2);
  EXPECT_EQ(h.chi2(), g.chi2());
  // An edge naming a vertex out of range is refused, though the frame is intact.
  StateWriter w;
  w.count(0);
  w.count(1);
  w.i32(0);
  w.i32(5);
  w.matrix(Eigen::Vector3d::Zero());
  w.matrix(Eigen::Matrix3d::Identity());
  w.count(0);
  EXPECT_THROW(object_from_state<PoseGraph2D>(frame_state("PoseGraph2D", w.payload()), "state"), StateError);
}

// Landmark world for the filters: a ring of landmarks, a robot circling inside.
struct LandmarkWorld {
  std::vector<Eigen::Vector2d> landmarks;
  LandmarkWorld() {
    for (int k = 0; k < 12; ++k) landmarks.emplace_back(6 * std::cos(0.5 * k), 6 * std::sin(0.5 * k));
  }
  void scan(const Eigen::Vector3d& x, std::mt19937& rng, RowMatrixXd& z, std::vector<long>& ids) const {
    std::normal_distribution<double> n(0.0, 0.05);
    std::vector<Eigen::Vector2d> rows;
    ids.clear();
    for (std::size_t i = 0; i < landmarks.size(); ++i) {
      Eigen::Vector2d m = range_bearing(x, landmarks[i]);
      if (m[0] > 7.0) continue;
      rows.emplace_back(m[0] + n(rng), m[1] + 0.1 * n(rng));
      ids.push_back(static_cast<long>(i));
    }
    z.resize(static_cast<Eigen::Index>(rows.size()), 2);
    for (std::size_t k = 0; k < rows.size(); ++k) z.row(static_cast<Eigen::Index>(k)) = rows[k].transpose();
  }
};

// Steps [from, to) of the circling robot on any filter with predict and a per-step update.
template <typename Step>
void drive(int from, int to, Step&& step) {
  LandmarkWorld w;
  std::mt19937 rng(11);
  for (int t = 0; t < to; ++t) {
    const Eigen::Vector3d x(3 * std::cos(0.1 * t), 3 * std::sin(0.1 * t), 0.1 * t + 1.5707963);
    RowMatrixXd z;
    std::vector<long> ids;
    w.scan(x, rng, z, ids);
    if (t >= from) step(t, z, ids);
  }
}

void expect_same_fastslam(const FastSlam& a, const FastSlam& b) {
  EXPECT_EQ(state_bytes(a), state_bytes(b));
  EXPECT_TRUE((a.poses().array() == b.poses().array()).all());
  EXPECT_TRUE((a.log_weights().array() == b.log_weights().array()).all());
  for (int k = 0; k < a.num_particles(); ++k) {
    const auto la = a.landmarks(k), lb = b.landmarks(k);
    ASSERT_EQ(la.size(), lb.size());
    for (std::size_t i = 0; i < la.size(); ++i) {
      EXPECT_EQ(la[i].id, lb[i].id);
      EXPECT_TRUE((la[i].mean.array() == lb[i].mean.array()).all());
      EXPECT_TRUE((la[i].cov.array() == lb[i].cov.array()).all());
    }
    EXPECT_TRUE((a.path(k).array() == b.path(k).array()).all());
  }
}

// Run N steps, save, load, run M more == N + M straight, for both versions and both kinds of
// correspondence. Version 2 is saved between two predicts (a pending composed prior).
TEST(StateFile, FastSlamResumedEqualsUninterrupted) {
  for (int version : {1, 2})
    for (bool known : {true, false}) {
      FastSlamOptions o;
      o.num_particles = 20;
      o.version = version;
      o.seed = 5;
      o.min_sightings = 2;  // a non-default option travels too
      const Eigen::MatrixXd r = Eigen::Vector3d(0.01, 0.01, 0.002).asDiagonal();
      const Eigen::MatrixXd q = Eigen::Vector2d(0.0025, 0.0001).asDiagonal();
      const Eigen::Vector3d x0(0.5, -1.0, 0.25);
      FastSlam first(r, q, o, x0);
      const auto step = [&](FastSlam& f) {
        return [&f, known](int t, const RowMatrixXd& z, const std::vector<long>& ids) {
          f.predict(0.3, 0.1, 1.0);
          f.predict(0.05, 0.0, 1.0);
          if (t % 3 == 2) return;  // updates skipped: the prior composes over several moves
          if (known) f.update(z, ids);
          else f.update_unknown(z);
        };
      };
      drive(0, 14, step(first));
      first.predict(0.3, 0.1, 1.0);  // pending motion at the save
      FastSlam resumed = round_trip<FastSlam, EkfSlam>(first, "fastslam");
      expect_same_fastslam(resumed, first);
      drive(14, 30, step(resumed));
      // The uninterrupted run: the same calls without the save and load.
      FastSlam reference(r, q, o, x0);
      drive(0, 14, step(reference));
      reference.predict(0.3, 0.1, 1.0);
      drive(14, 30, step(reference));
      expect_same_fastslam(resumed, reference);
    }
}

TEST(StateFile, EkfSlamResumedEqualsUninterrupted) {
  const Eigen::Matrix3d r = Eigen::Vector3d(0.01, 0.01, 0.002).asDiagonal();
  const Eigen::Matrix2d q = Eigen::Vector2d(0.0025, 0.0001).asDiagonal();
  for (bool known : {true, false}) {
    EkfSlam a(r, q, false, {3, 0, 1.5707963}, Eigen::Matrix3d::Zero()), b = a;
    MapManagement mm;
    mm.provisional = true;
    mm.existence = true;
    a.set_map_management(mm);
    b.set_map_management(mm);
    const auto step = [&](EkfSlam& f) {
      return [&f, known](int, const RowMatrixXd& z, const std::vector<long>& ids) {
        f.predict(0.3, 0.1, 1.0);
        if (known) f.update(z, ids);
        else f.update_unknown(z, 9.0, 20.0);
      };
    };
    drive(0, 25, step(a));
    drive(0, 10, step(b));
    EkfSlam c = round_trip<EkfSlam, FastSlam>(b, "ekf");
    EXPECT_EQ(c.num_provisional(), b.num_provisional());
    drive(10, 25, step(c));
    EXPECT_TRUE((c.mean().array() == a.mean().array()).all());
    EXPECT_TRUE((c.covariance().array() == a.covariance().array()).all());
    EXPECT_EQ(c.landmark_ids(), a.landmark_ids());
    EXPECT_EQ(c.num_provisional(), a.num_provisional());
  }
}

TEST(StateFile, MultiHypothesisEkfSlamResumedEqualsUninterrupted) {
  const Eigen::Matrix3d r = Eigen::Vector3d(0.01, 0.01, 0.002).asDiagonal();
  const Eigen::Matrix2d q = Eigen::Vector2d(0.0025, 0.0001).asDiagonal();
  const EkfSlam e(r, q, false, {3, 0, 1.5707963}, Eigen::Matrix3d::Zero());
  MultiHypothesisOptions o;
  o.bearing_offset_sigma = 0.01;
  MultiHypothesisEkfSlam a(e, o), b(e, o);
  const auto step = [](MultiHypothesisEkfSlam& f) {
    return [&f](int, const RowMatrixXd& z, const std::vector<long>&) {
      f.predict(0.3, 0.1, 1.0);
      f.update(z);
    };
  };
  drive(0, 16, step(a));
  drive(0, 8, step(b));
  MultiHypothesisEkfSlam c = round_trip<MultiHypothesisEkfSlam, EkfSlam>(b, "mht");
  EXPECT_EQ(c.history(), b.history());
  drive(8, 16, step(c));
  EXPECT_EQ(state_bytes(c), state_bytes(a));
  EXPECT_EQ(c.costs(), a.costs());
  EXPECT_EQ(c.history(), a.history());
  EkfSlam best_c = c.best(), best_a = a.best();
  EXPECT_TRUE((best_c.mean().array() == best_a.mean().array()).all());
}

// Laser scans of the room along a loop, with odometry that drifts.
struct RoomRun {
  Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(181, -1.5707963, 1.5707963);
  std::vector<Eigen::Vector3d> truth, odometry;
  RoomRun() {
    std::mt19937 rng(3);
    std::normal_distribution<double> n(0.0, 0.01);
    Eigen::Vector3d odo(0, 0, 0);
    for (int t = 0; t < 120; ++t) {
      const double a = 0.06 * t;
      truth.emplace_back(2.5 * std::cos(a) - 2.5, 2.0 * std::sin(a), a + 1.5707963);
      if (t > 0) odo += truth[t] - truth[t - 1] + Eigen::Vector3d(n(rng), n(rng), 0.2 * n(rng));
      odometry.push_back(odo);
    }
  }
  template <typename Mapper>
  void feed(Mapper& m, int from, int to) const {
    for (int t = from; t < to; ++t)
      m.add_scan(cast(truth[t], angles, room_walls()), angles, odometry[t], 0.1 * t);
  }
};

// The room's run fed straight through, and saved at scan 70, loaded and fed the rest: the two
// states are the same bytes.
template <typename Mapper, typename Other, typename Options>
std::pair<Mapper, Mapper> straight_and_resumed(const Options& o, const char* name) {
  const RoomRun run;
  Mapper straight(o), first(o);
  run.feed(straight, 0, 120);
  run.feed(first, 0, 70);
  Mapper resumed = round_trip<Mapper, Other>(first, name);
  run.feed(resumed, 70, 120);
  EXPECT_EQ(state_bytes(resumed), state_bytes(straight));
  return {std::move(straight), std::move(resumed)};
}

TEST(StateFile, IncrementalScanMatcherResumedEqualsUninterrupted) {
  IncrementalScanMatcherOptions o;
  o.submap_distance = 3.0;
  o.filter.max_usable_range = 8.0;
  const auto runs = straight_and_resumed<IncrementalScanMatcher, SubmapSlam2D>(o, "matcher");
  EXPECT_GT(runs.second.submaps().size(), 1u);
}

TEST(StateFile, SubmapSlam2DResumedEqualsUninterrupted) {
  SubmapSlamOptions o;
  o.frontend.submap_distance = 3.0;
  o.frontend.filter.max_usable_range = 8.0;
  auto [straight, resumed] = straight_and_resumed<SubmapSlam2D, GridFastSlam>(o, "submaps");
  straight.finish();
  resumed.finish();
  const auto a = straight.scan_poses(), b = resumed.scan_poses();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE((a[k].array() == b[k].array()).all());
  EXPECT_TRUE((straight.map().log_odds().array() == resumed.map().log_odds().array()).all());
}

TEST(StateFile, GridFastSlamResumedEqualsUninterrupted) {
  for (GridProposal proposal : {GridProposal::kScanMatching, GridProposal::kImprovedOdometry}) {
    GridFastSlamOptions o;
    o.num_particles = 6;
    o.proposal = proposal;
    o.resolution = 0.1;
    o.filter.max_usable_range = 8.0;
    o.update.distance = 0.2;
    o.seed = 4;
    const RoomRun run;
    GridFastSlam straight(o), first(o);
    run.feed(straight, 0, 90);
    run.feed(first, 0, 45);
    GridFastSlam resumed = round_trip<GridFastSlam, SubmapSlam2D>(first, "rbpf");
    EXPECT_EQ(resumed.tile_sharing().distinct, first.tile_sharing().distinct);
    EXPECT_EQ(resumed.tile_sharing().references, first.tile_sharing().references);
    run.feed(resumed, 45, 90);
    EXPECT_EQ(state_bytes(resumed), state_bytes(straight));
    EXPECT_TRUE((resumed.poses().array() == straight.poses().array()).all());
    EXPECT_TRUE((resumed.log_weights().array() == straight.log_weights().array()).all());
    const int k = straight.best_index();
    EXPECT_TRUE((resumed.scan_poses(k).array() == straight.scan_poses(k).array()).all());
    EXPECT_TRUE((resumed.map(k).log_odds().array() == straight.map(k).log_odds().array()).all());
  }
}

// The room mapped from a few poses: a saved map to start runs from.
OccupancyGrid2D room_map(double resolution) {
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(361, -3.1415926, 3.1415926);
  OccupancyGrid2D g = OccupancyGrid2D::covering(-6.0, -4.0, 2.0, 4.0, resolution);
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(-2.5, 0.0, 0.0), Eigen::Vector3d(-4.0, 1.0, 1.0),
                                   Eigen::Vector3d(-1.0, -1.0, 2.0)})
    g.insert_rays(p, cast(p, angles, room_walls()), angles, 30.0);
  return g;
}

TEST(StateFile, RunsFromASavedMapResumeAsUninterrupted) {
  // The saved map travels in the state, before and after the first scan.
  const RoomRun run;
  {
    SubmapSlamOptions o;
    o.frontend.submap_distance = 3.0;
    o.frontend.filter.max_usable_range = 8.0;
    SubmapSlam2D straight(o), first(o);
    straight.start_from_map(room_map(o.frontend.resolution), run.truth[0]);
    first.start_from_map(room_map(o.frontend.resolution), run.truth[0]);
    SubmapSlam2D empty = round_trip<SubmapSlam2D, GridFastSlam>(first, "submaps_map0");  // before any scan
    ASSERT_NE(empty.start_map(), nullptr);
    run.feed(straight, 0, 120);
    run.feed(empty, 0, 60);
    SubmapSlam2D resumed = round_trip<SubmapSlam2D, GridFastSlam>(empty, "submaps_map");
    run.feed(resumed, 60, 120);
    EXPECT_EQ(state_bytes(resumed), state_bytes(straight));
  }
  {
    GridFastSlamOptions o;
    o.num_particles = 4;
    o.filter.max_usable_range = 8.0;
    o.seed = 2;
    GridFastSlam straight(o), first(o);
    straight.start_from_map(room_map(o.resolution), run.truth[0]);
    first.start_from_map(room_map(o.resolution), run.truth[0]);
    run.feed(straight, 0, 60);
    run.feed(first, 0, 30);
    GridFastSlam resumed = round_trip<GridFastSlam, SubmapSlam2D>(first, "rbpf_map");
    ASSERT_NE(resumed.start_map(), nullptr);
    run.feed(resumed, 30, 60);
    EXPECT_EQ(state_bytes(resumed), state_bytes(straight));
  }
}

TEST(StateFile, OccupancyGrid3D) {
  OccupancyGrid3D g(0.2, {0.75, 0.35, 0.1, 0.95, 0.55});
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  auto cloud = [&] {
    Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> pts(200, 3);
    for (Eigen::Index i = 0; i < pts.rows(); ++i) pts.row(i) << u(rng), u(rng), 0.3 * u(rng);
    return pts;
  };
  g.insert_point_cloud(cloud(), Eigen::Vector3d(0.1, -0.2, 0.3));
  g.set_log_odds(g.key_of(9.0, 9.0, 9.0), 1.0f);
  g.set_log_odds(g.key_of(9.0, 9.0, 9.0), std::nanf(""));  // a block with no known voxel
  OccupancyGrid3D h = round_trip<OccupancyGrid3D, OccupancyGrid2D>(g, "grid3d");
  EXPECT_EQ(h.resolution(), g.resolution());
  EXPECT_EQ(h.params().occupancy_threshold, 0.55);
  EXPECT_EQ(h.num_blocks(), g.num_blocks());
  EXPECT_EQ(h.num_known_voxels(), g.num_known_voxels());
  // Both continue alike: the same voxels in the same blocks after the next scan.
  const auto next = cloud();
  g.insert_point_cloud(next, Eigen::Vector3d::Zero());
  h.insert_point_cloud(next, Eigen::Vector3d::Zero());
  EXPECT_EQ(state_bytes(h), state_bytes(g));
  // Damaged payloads inside a valid frame: a key beyond the range, a repeated key, a voxel
  // outside the clamp bounds.
  auto payload = [&](std::uint64_t key1, std::uint64_t key2, float value) {
    StateWriter w;
    w.f64(0.2);
    for (double v : {0.7, 0.4, 0.1192, 0.971, 0.5}) w.f64(v);
    w.count(2);
    for (std::uint64_t key : {key1, key2}) {
      w.u64(key);
      for (int i = 0; i < OccupancyGrid3D::kBlockVoxels; ++i) w.f32(i == 3 ? value : std::nanf(""));
    }
    return frame_state(OccupancyGrid3D::kStateTag, w.payload());
  };
  auto refused = [](const std::string& bytes, const std::string& what) {
    try {
      object_from_state<OccupancyGrid3D>(bytes, "state");
      ADD_FAILURE() << "accepted " << what;
    } catch (const StateError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  EXPECT_NO_THROW(object_from_state<OccupancyGrid3D>(payload(1, 2, 0.5f), "state"));
  refused(payload(1, std::uint64_t{1} << 50, 0.5f), "key outside");
  refused(payload(1, 8192, 0.5f), "key outside");  // a block coordinate beyond 65536 / 8
  refused(payload(1, 1, 0.5f), "repeats");
  refused(payload(1, 2, 9.0f), "clamp bounds");
}

// PoseGraph3D: poses, a point, edges, a prior and a point edge with a sensor offset; the loaded
// graph equals the saved one and continues alike.
TEST(StateFile, PoseGraph3D) {
  PoseGraph3D g;
  Matrix6d info = Matrix6d::Identity();
  info(0, 1) = info(1, 0) = 0.2;
  for (int k = 0; k < 4; ++k)
    g.add_pose(k, {Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d(0.2, 0.5, 1.0).normalized())),
                   Eigen::Vector3d(k, 0.5 * k, 0.1)});
  g.add_point(10, {1.0, 2.0, 0.5});
  for (int k = 0; k + 1 < 4; ++k) g.add_pose_edge(k, k + 1, {Eigen::Quaterniond(0.99, 0.1, 0.0, 0.05).normalized(), {1, 0.4, 0.1}}, info);
  g.add_pose_prior(0, {}, 10.0 * Matrix6d::Identity());
  g.add_point_edge(2, 10, {0.1, 1.2, 0.3}, 2.0 * Eigen::Matrix3d::Identity(),
                   {Eigen::Quaterniond(0.98, 0.0, 0.2, 0.0).normalized(), {0.1, 0.0, 0.3}});
  g.set_fixed(1);
  PoseGraph3D h = round_trip<PoseGraph3D, PoseGraph2D>(g, "graph3d");
  EXPECT_EQ(h.num_vertices(), g.num_vertices());
  EXPECT_EQ(h.num_points(), 1);
  EXPECT_TRUE(h.vertex(h.index_of(1)).fixed);
  EXPECT_EQ(h.chi2(), g.chi2());
  // A point edge naming a pose as its point is refused.
  StateWriter w;
  h.write_state(w);
  std::string payload = w.payload();
  const std::size_t point_edge = payload.size() - (4 + 4 + 16 + 24 + 16 + 72 + 56);
  payload[point_edge + 4] = 0;  // its point index: vertex 0, a pose
  EXPECT_THROW(object_from_state<PoseGraph3D>(frame_state("PoseGraph3D", payload), "state"), StateError);
  g.add_pose_edge(3, 0, {}, Matrix6d::Identity());
  h.add_pose_edge(3, 0, {}, Matrix6d::Identity());
  EXPECT_EQ(state_bytes(h), state_bytes(g));
}

// MonteCarloLocalization: part way through tracking in a room, saved and loaded; both go on
// alike (particles, weights, random streams), and a state with more particles than
// max_particles is refused.
TEST(StateFile, MonteCarloLocalization) {
  OccupancyGrid2D map(0.1, 100, 80, {-5.0, -4.0});
  map.log_odds().setConstant(-3.0);
  const auto walls = room_walls();
  for (int r = 0; r < 80; ++r)
    for (int c = 0; c < 100; ++c) {
      const double x = -5.0 + 0.1 * (c + 0.5), y = -4.0 + 0.1 * (r + 0.5);
      if (std::abs(x) > 4.85 || std::abs(y) > 3.85) map.log_odds()(r, c) = 3.0;
    }
  MonteCarloLocalizationOptions o;
  o.min_particles = 50;
  o.max_particles = 200;
  o.seed = 3;
  MonteCarloLocalization mcl(map, o);
  mcl.initialize_pose({0.0, 0.0, 0.2}, Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal());
  const Eigen::VectorXd angles = Eigen::VectorXd::LinSpaced(60, -1.5, 1.5);
  Eigen::Vector3d pose(0.0, 0.0, 0.2);
  const auto step = [&](MonteCarloLocalization& f, const Eigen::Vector3d& at) {
    f.predict_odometry({0.3, 0.0, 0.05});
    f.update(cast(at, angles, walls), angles);
  };
  for (int k = 0; k < 3; ++k) {
    pose = Pose2::from_vector(pose).compose(Pose2::from_vector({0.3, 0.0, 0.05})).vector();
    step(mcl, pose);
  }
  mcl.predict_odometry({0.1, 0.0, 0.0});  // motion not yet applied is state too
  MonteCarloLocalization loaded = round_trip<MonteCarloLocalization, PoseGraph2D>(mcl, "mcl");
  EXPECT_EQ(loaded.num_particles(), mcl.num_particles());
  EXPECT_TRUE((loaded.pose().array() == mcl.pose().array()).all());
  for (int k = 0; k < 3; ++k) {
    pose = Pose2::from_vector(pose).compose(Pose2::from_vector({0.3, 0.0, 0.05})).vector();
    step(mcl, pose);
    step(loaded, pose);
  }
  EXPECT_EQ(state_bytes(loaded), state_bytes(mcl));
  EXPECT_TRUE((loaded.poses().array() == mcl.poses().array()).all());
  // Options: the sensor model (1 byte), odometry noise, thresholds and likelihood field (8
  // doubles), beam model (7), max and min range (2), max_beams, weight_scale, then
  // min_particles and max_particles.
  StateWriter w;
  mcl.write_state(w);
  std::string payload = w.payload();
  const std::size_t min_particles = 1 + 8 * 8 + 7 * 8 + 2 * 8 + 4 + 8;
  StateWriter counts;
  counts.i32(1);
  counts.i32(mcl.num_particles() - 1);
  payload.replace(min_particles, 8, counts.payload());
  try {
    object_from_state<MonteCarloLocalization>(frame_state("MonteCarloLocalization", payload), "state");
    ADD_FAILURE() << "more particles than max_particles loaded";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("particles, outside [1, max_particles"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace probslam
