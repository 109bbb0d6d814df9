#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <thread>
#include <unordered_set>
#include <vector>

#include "probslam/core/range_bearing_model.hpp"
#include "probslam/fastslam/fast_slam.hpp"
#include "probslam/fastslam/landmark_tree.hpp"
#include "probslam/fastslam/node_pool.hpp"
#include "test_support.hpp"

using namespace probslam;
using probslam::test_support::expect_invalid;

namespace {

using Reference = std::map<long, Landmark>;

bool same_landmark(const Landmark& a, const Landmark& b) {
  return a.id == b.id && a.mean == b.mean && a.cov == b.cov && a.existence == b.existence;
}

// Every query of the persistent map against the deep-copy reference.
void expect_equal(const LandmarkMap& map, const Reference& ref, std::mt19937& rng) {
  ASSERT_EQ(map.size(), ref.size());
  for (const auto& [id, lm] : ref) {
    const Landmark* found = map.find(id);
    ASSERT_NE(found, nullptr) << id;
    EXPECT_TRUE(same_landmark(*found, lm)) << id;
  }
  EXPECT_EQ(map.find(-5), nullptr);
  std::size_t visited = 0;
  map.for_each([&](const Landmark& lm) {
    ++visited;
    const auto it = ref.find(lm.id);
    ASSERT_NE(it, ref.end());
    EXPECT_TRUE(same_landmark(it->second, lm));
  });
  EXPECT_EQ(visited, ref.size());
  std::uniform_real_distribution<double> u(-25.0, 25.0), r(0.0, 8.0);
  const Eigen::Vector2d c(u(rng), u(rng));
  const double radius = r(rng);
  std::vector<long> got, want;
  map.for_each_within(c, radius, [&](const Landmark& lm) { got.push_back(lm.id); });
  for (const auto& [id, lm] : ref)
    if ((lm.mean - c).squaredNorm() <= radius * radius) want.push_back(id);
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, want);
  // Several discs in one walk (a scan's measurements): the same (disc, landmark) pairs as the
  // brute force, each once; a disc of negative radius holds nothing, an infinite one everything.
  std::vector<LandmarkMap::Disc> discs;
  for (int i = 0; i < 5; ++i) discs.push_back({Eigen::Vector2d(u(rng), u(rng)), r(rng)});
  discs.push_back({Eigen::Vector2d(u(rng), u(rng)), -1.0});
  discs.push_back({Eigen::Vector2d(u(rng), u(rng)), std::numeric_limits<double>::infinity()});
  std::vector<std::pair<std::size_t, long>> got_pairs, want_pairs;
  map.for_each_within_any(discs, [&](const Landmark& lm, std::size_t i) { got_pairs.emplace_back(i, lm.id); });
  for (std::size_t i = 0; i < discs.size(); ++i)
    for (const auto& [id, lm] : ref)
      if ((lm.mean - discs[i].center).squaredNorm() <= discs[i].radius * discs[i].radius && discs[i].radius >= 0.0)
        want_pairs.emplace_back(i, id);
  std::sort(got_pairs.begin(), got_pairs.end());
  EXPECT_EQ(got_pairs, want_pairs);
}

// BST order on keys, heap order on priorities, sizes: the treap's invariants.
template <class Tree>
std::size_t check_treap(const typename Tree::Node* n) {
  if (!n) return 0;
  if (n->left) {
    EXPECT_TRUE(n->left->key < n->key);
    EXPECT_LE(n->left->priority, n->priority);
  }
  if (n->right) {
    EXPECT_TRUE(n->key < n->right->key);
    EXPECT_LE(n->right->priority, n->priority);
  }
  const std::size_t size = 1 + check_treap<Tree>(n->left.get()) + check_treap<Tree>(n->right.get());
  EXPECT_EQ(size, n->size);
  return size;
}

FastSlamOptions options(int particles, int version) {
  FastSlamOptions o;
  o.num_particles = particles;
  o.version = version;
  o.seed = 7;
  return o;
}

// The motion and measurement noise of the tests' filters.
const Eigen::MatrixXd kMotionNoise = Eigen::Vector3d(0.02, 0.02, 0.005).asDiagonal();
const Eigen::MatrixXd kMeasurementNoise = Eigen::Vector2d(0.01, 0.001).asDiagonal();

FastSlam filter(const FastSlamOptions& o) { return FastSlam(kMotionNoise, kMeasurementNoise, o); }

// A small world and a noisy drive around it: measurements (k x 2) and ids per step.
struct World {
  std::vector<Eigen::Vector2d> landmarks;
  std::vector<RowMatrixXd> z;
  std::vector<std::vector<long>> ids;
};

World make_world(int steps, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::normal_distribution<double> nr(0.0, 0.1), nb(0.0, 0.03);
  World w;
  for (int i = 0; i < 25; ++i) w.landmarks.emplace_back(u(rng), u(rng));
  Eigen::Vector3d x(0.0, -6.0, 0.0);
  for (int t = 0; t < steps; ++t) {
    x = Eigen::Vector3d(x[0] + 0.2 * std::cos(x[2]), x[1] + 0.2 * std::sin(x[2]), x[2] + 0.033);
    std::vector<Eigen::Vector2d> rows;
    std::vector<long> ids;
    for (int i = 0; i < 25; ++i) {
      const Eigen::Vector2d z = range_bearing(x, w.landmarks[static_cast<std::size_t>(i)]);
      if (z[0] < 6.0 && std::abs(z[1]) < 1.5) {
        rows.emplace_back(z[0] + nr(rng), z[1] + nb(rng));
        ids.push_back(i);
      }
    }
    RowMatrixXd zm(static_cast<Eigen::Index>(rows.size()), 2);
    for (std::size_t k = 0; k < rows.size(); ++k) zm.row(static_cast<Eigen::Index>(k)) = rows[k].transpose();
    w.z.push_back(zm);
    w.ids.push_back(ids);
  }
  return w;
}

void drive(FastSlam& f, const World& w, bool unknown) {
  for (std::size_t t = 0; t < w.z.size(); ++t) {
    f.predict(1.0, 0.165, 0.2);
    if (unknown) f.update_unknown(w.z[t]);
    else f.update(w.z[t], w.ids[t]);
  }
}

bool same_state(const FastSlam& a, const FastSlam& b) {
  if (a.poses() != b.poses() || a.log_weights() != b.log_weights()) return false;
  for (int k = 0; k < a.num_particles(); ++k) {
    const std::vector<Landmark> la = a.landmarks(k), lb = b.landmarks(k);
    if (la.size() != lb.size()) return false;
    for (std::size_t i = 0; i < la.size(); ++i)
      if (!same_landmark(la[i], lb[i])) return false;
    if (a.path(k) != b.path(k)) return false;
  }
  return true;
}

}  // namespace

TEST(LandmarkTree, RandomisedAgainstDeepCopies) {
  const long live_before = g_persistent_tree_nodes.load();
  {
    std::mt19937 rng(11);
    constexpr int kMaps = 24;
    std::vector<LandmarkMap> maps(kMaps, LandmarkMap(1.5));
    std::vector<Reference> refs(kMaps);
    std::uniform_int_distribution<int> pick(0, kMaps - 1), op(0, 9), id_of(0, 199);
    std::uniform_real_distribution<double> coord(-20.0, 20.0), step(-2.0, 2.0);
    for (int n = 0; n < 6000; ++n) {
      const int k = pick(rng);
      const int what = op(rng);
      if (what <= 4) {  // insert or update (possibly moving the landmark to another cell)
        const long id = id_of(rng);
        Landmark lm;
        const auto it = refs[k].find(id);
        if (it != refs[k].end()) {
          lm = it->second;
          lm.mean += Eigen::Vector2d(step(rng), step(rng));
        } else {
          lm.id = id;
          lm.mean = Eigen::Vector2d(coord(rng), coord(rng));
        }
        lm.cov = Eigen::Matrix2d::Identity() * (1.0 + n);
        lm.existence = n;
        maps[k].put(lm);
        refs[k][id] = lm;
      } else if (what <= 6) {  // erase
        const long id = id_of(rng);
        EXPECT_EQ(maps[k].erase(id), refs[k].erase(id) == 1);
      } else {  // a resampling step: particle j becomes a copy of particle k
        const int j = pick(rng);
        maps[j] = maps[k];
        refs[j] = refs[k];
      }
      if (n % 50 == 0)
        for (int m = 0; m < kMaps; ++m) expect_equal(maps[m], refs[m], rng);
    }
    for (int m = 0; m < kMaps; ++m) {
      expect_equal(maps[m], refs[m], rng);
      check_treap<LandmarkMap::SpatialTree>(maps[m].spatial_tree().root());
      check_treap<LandmarkMap::IdTree>(maps[m].id_tree().root());
    }
  }
  EXPECT_EQ(g_persistent_tree_nodes.load(), live_before);  // every node freed
}

TEST(LandmarkTree, CopyIsConstantAndUpdateCopiesOnePath) {
  LandmarkMap map(2.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-500.0, 500.0);
  for (long id = 0; id < 20000; ++id) {
    Landmark lm;
    lm.id = id;
    lm.mean = Eigen::Vector2d(coord(rng), coord(rng));
    map.put(lm);
  }
  const long before = g_persistent_tree_nodes.load();
  std::vector<LandmarkMap> copies(100, map);  // a resampling of 100 copies
  EXPECT_EQ(g_persistent_tree_nodes.load(), before);
  Landmark lm = *copies[3].find(1234);
  lm.cov(0, 0) = 5.0;  // an update within the cell: one path of the spatial tree
  copies[3].put(lm);
  const long added = g_persistent_tree_nodes.load() - before;
  EXPECT_GT(added, 0);
  EXPECT_LT(added, 80);  // depth of a treap of 20000 keys: ~2 ln N = 20 expected
  EXPECT_EQ(map.find(1234)->cov(0, 0), 0.0);
  EXPECT_EQ(copies[4].find(1234)->cov(0, 0), 0.0);
  // The path the update copied is copies[3]'s alone: updating the landmark again changes those
  // nodes in place (no node built), and no other handle sees it.
  const long after_first = g_persistent_tree_nodes.load();
  lm.cov(1, 1) = 7.0;
  copies[3].put(lm);
  EXPECT_EQ(g_persistent_tree_nodes.load(), after_first);
  EXPECT_EQ(copies[3].find(1234)->cov(1, 1), 7.0);
  EXPECT_EQ(copies[4].find(1234)->cov(1, 1), 0.0);
  EXPECT_EQ(map.find(1234)->cov(1, 1), 0.0);
  check_treap<LandmarkMap::SpatialTree>(copies[3].spatial_tree().root());
  lm.mean += Eigen::Vector2d(10.0, 10.0);  // moves cells: erase + insert + the id tree's path
  copies[3].put(lm);
  EXPECT_LT(g_persistent_tree_nodes.load() - before, 400);
  EXPECT_NE(map.find(1234)->mean, lm.mean);
}

TEST(LandmarkTree, LongPathsAreFreedWithoutRecursion) {
  PosePath path;
  for (int i = 0; i < 2000000; ++i) path.push(Eigen::Vector3d(i, 0.0, 0.0));
  PosePath copy = path;
  path = PosePath();
  EXPECT_EQ(copy.size(), 2000000u);
  copy = PosePath();  // must not overflow the stack
  EXPECT_EQ(copy.size(), 0u);
}

// Chunked pose paths against a plain vector per path: random pushes, pops, replacements, copies
// and resets over 12 paths sharing chunks, every path compared after every operation.
TEST(PosePathChunks, MatchVectorsUnderRandomCopiesAndEdits) {
  std::mt19937 rng(11);
  constexpr int kPaths = 12;
  std::vector<PosePath> paths(kPaths);
  std::vector<std::vector<Eigen::Vector3d>> reference(kPaths);
  auto pose = [&] { return Eigen::Vector3d(std::uniform_real_distribution<double>(-9.0, 9.0)(rng), 0.5, -0.25); };
  for (int step = 0; step < 6000; ++step) {
    const int i = static_cast<int>(rng() % kPaths), j = static_cast<int>(rng() % kPaths);
    switch (rng() % 10) {
      case 0: case 1: case 2: case 3: {
        const Eigen::Vector3d x = pose();
        paths[i].push(x);
        reference[i].push_back(x);
        break;
      }
      case 4:
        paths[i].pop();
        if (!reference[i].empty()) reference[i].pop_back();
        break;
      case 5: {
        const Eigen::Vector3d x = pose();
        paths[i].replace_last(x);
        if (reference[i].empty()) reference[i].push_back(x);
        else reference[i].back() = x;
        break;
      }
      case 6: case 7: case 8:
        paths[j] = paths[i];  // a resampled copy
        reference[j] = reference[i];
        break;
      default:
        if (rng() % 20 == 0) {
          paths[i] = PosePath();
          reference[i].clear();
        }
    }
    for (int k = 0; k < kPaths; ++k) {
      ASSERT_EQ(paths[k].size(), reference[k].size());
      const Poses2 got = paths[k].poses();
      for (std::size_t r = 0; r < reference[k].size(); ++r)
        ASSERT_EQ(Eigen::Vector3d(got.row(static_cast<Eigen::Index>(r)).transpose()), reference[k][r]) << "step " << step;
    }
  }
}

TEST(PosePathChunks, CopiesShareChunksAndAppendOneChunkPerSixteenPoses) {
  PosePath path;
  for (int i = 0; i < 1000; ++i) path.push(Eigen::Vector3d(i, 0.0, 0.0));
  std::vector<PosePath> copies(100, path);
  std::unordered_set<const void*> seen;
  std::size_t chunks = 0;
  for (const PosePath& c : copies) chunks += c.collect_nodes(seen);
  EXPECT_EQ(chunks, static_cast<std::size_t>((1000 + PosePath::kChunkPoses - 1) / PosePath::kChunkPoses));
  // The first copy to append takes the free slot of the shared chunk; each other starts a chunk.
  for (PosePath& c : copies) c.push(Eigen::Vector3d(-1.0, 0.0, 0.0));
  for (const PosePath& c : copies) chunks += c.collect_nodes(seen);
  EXPECT_LE(chunks, 63u + 100u);
  for (const PosePath& c : copies) {
    const Poses2 p = c.poses();
    ASSERT_EQ(p.rows(), 1001);
    EXPECT_EQ(p(999, 0), 999.0);
    EXPECT_EQ(p(1000, 0), -1.0);
  }
}

// Two threads append to copies of one path at once, as two workers do after a resampling: one
// claims the shared chunk's free slot, the other starts a chunk, and neither sees the other's.
TEST(PosePathChunks, ConcurrentAppendsToSharedCopiesStayApart) {
  for (int trial = 0; trial < 300; ++trial) {
    PosePath base;
    for (int i = 0; i < 5 + trial % 20; ++i) base.push(Eigen::Vector3d(i, 0.0, 0.0));
    PosePath a = base, b = base;
    std::thread ta([&] {
      for (int i = 0; i < 40; ++i) a.push(Eigen::Vector3d(100.0 + i, 1.0, 0.0));
    });
    std::thread tb([&] {
      for (int i = 0; i < 40; ++i) b.push(Eigen::Vector3d(200.0 + i, 2.0, 0.0));
    });
    ta.join();
    tb.join();
    const Poses2 pa = a.poses(), pb = b.poses(), p0 = base.poses();
    const Eigen::Index n = p0.rows();
    ASSERT_EQ(pa.rows(), n + 40);
    ASSERT_EQ(pb.rows(), n + 40);
    EXPECT_EQ(pa.topRows(n), p0);
    EXPECT_EQ(pb.topRows(n), p0);
    for (int i = 0; i < 40; ++i) {
      ASSERT_EQ(pa(n + i, 0), 100.0 + i);
      ASSERT_EQ(pb(n + i, 0), 200.0 + i);
    }
  }
}

TEST(FastSlam, ResamplerCountsAreFloorOrCeil) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + trial % 37;
    Eigen::VectorXd w(m);
    for (int k = 0; k < m; ++k) w[k] = std::pow(u(rng), 3.0);
    w /= w.sum();
    const std::vector<int> idx = low_variance_resample(w, u(rng));
    std::vector<int> count(m, 0);
    for (int i : idx) ++count[i];
    for (int k = 0; k < m; ++k) {
      EXPECT_GE(count[k], std::floor(m * w[k] - 1e-9));
      EXPECT_LE(count[k], std::ceil(m * w[k] + 1e-9));
    }
    EXPECT_TRUE(std::is_sorted(idx.begin(), idx.end()));
  }
  expect_invalid([] { low_variance_resample(Eigen::VectorXd::Zero(3), 0.5); }, "weights");
  expect_invalid([] { low_variance_resample(Eigen::VectorXd::Ones(3), 1.0); }, "offset");
}

TEST(FastSlam, ProposalEqualsInformationForm) {
  const Eigen::Vector3d x(1.0, 2.0, 0.3);
  Eigen::Matrix3d r;
  r << 0.04, 0.01, 0.0, 0.01, 0.05, 0.002, 0.0, 0.002, 0.01;
  const Eigen::Vector2d m(4.0, 5.0);
  Eigen::Matrix2d sm;
  sm << 0.2, 0.05, 0.05, 0.1;
  const Eigen::Matrix2d q = Eigen::Vector2d(0.01, 0.002).asDiagonal();
  const Eigen::Vector2d z(4.1, 0.5);
  const PoseProposal p = fastslam2_proposal(x, r, m, sm, z, q);
  const MeasurementJacobians<2> j = range_bearing_jacobians(x, m);
  const Eigen::Matrix2d qj = j.landmark * sm * j.landmark.transpose() + q;
  const Eigen::Matrix3d cov = (j.pose.transpose() * qj.inverse() * j.pose + r.inverse()).inverse();
  Eigen::Vector2d nu = z - range_bearing(x, m);
  const Eigen::Vector3d mean = cov * j.pose.transpose() * qj.inverse() * nu + x;
  EXPECT_LT((p.mean - mean).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((p.cov - cov).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::Matrix2d s = j.pose * r * j.pose.transpose() + qj;
  const double ll = -0.5 * (nu.dot(s.inverse() * nu) + std::log((2 * M_PI) * (2 * M_PI) * s.determinant()));
  EXPECT_NEAR(p.log_likelihood, ll, 1e-12);
  expect_invalid([&] { fastslam2_proposal(x, -r, m, sm, z, q); }, "pose_cov");
  expect_invalid([&] { fastslam2_proposal(x, r, x.head<2>(), sm, z, q); }, "landmark_mean");
}

TEST(FastSlam, ThreadsGiveIdenticalResults) {
  const World w = make_world(60, 2);
  for (int version : {1, 2})
    for (bool unknown : {false, true}) {
      FastSlamOptions o = options(64, version);
      FastSlam one = filter(o);
      o.threads = 2;
      FastSlam two = filter(o);
      o.threads = 5;
      FastSlam five = filter(o);
      drive(one, w, unknown);
      drive(two, w, unknown);
      drive(five, w, unknown);
      EXPECT_GT(one.num_resamples(), 0);
      EXPECT_TRUE(same_state(one, two)) << version << unknown;
      EXPECT_TRUE(same_state(one, five)) << version << unknown;
    }
}

TEST(FastSlam, ResamplingSharesMaps) {
  const World w = make_world(40, 4);
  FastSlam f = filter(options(50, 1));
  drive(f, w, false);
  const MapSharing before = f.map_sharing();
  const long live = g_persistent_tree_nodes.load();
  FastSlam copy = f;
  copy.resample();
  EXPECT_EQ(g_persistent_tree_nodes.load(), live);  // copying maps allocates nothing
  EXPECT_LE(copy.map_sharing().distinct_nodes, before.distinct_nodes);
  EXPECT_EQ(before.total_nodes, 2 * before.landmarks);
  EXPECT_LT(before.distinct_nodes, before.total_nodes);
}

TEST(FastSlam, BadInputRaisesAndKeepsState) {
  const auto bad = [](auto change, const char* name) {
    FastSlamOptions o = options(4, 1);
    change(o);
    expect_invalid([&] { o.validate(); }, name);
    expect_invalid([&] { (void)filter(o); }, name);
  };
  bad([](FastSlamOptions& o) { o.num_particles = 0; }, "num_particles");
  bad([](FastSlamOptions& o) { o.num_particles = -3; }, "num_particles");
  bad([](FastSlamOptions& o) { o.version = 3; }, "version");
  bad([](FastSlamOptions& o) { o.threads = 0; }, "threads");
  bad([](FastSlamOptions& o) { o.resample_threshold = 1.5; }, "resample_threshold");
  bad([](FastSlamOptions& o) { o.p_new = 0.0; }, "p_new");
  bad([](FastSlamOptions& o) { o.cell_size = 0.0; }, "cell_size");
  bad([](FastSlamOptions& o) { o.association_radius = -1.0; }, "association_radius");
  bad([](FastSlamOptions& o) { o.negative_information = true; }, "sensor_range");
  bad([](FastSlamOptions& o) { o.sensor_fov = 7.0; }, "sensor_fov");
  bad([](FastSlamOptions& o) { o.min_sightings = 0; }, "min_sightings");
  bad([](FastSlamOptions& o) { o.bearing_offset_correlation = 1.0; }, "bearing_offset_correlation");
  // The model: the constructor's arguments.
  const FastSlamOptions o = options(4, 1);
  const auto bad_model = [&](const Eigen::MatrixXd& r, const Eigen::MatrixXd& q, const FastSlamOptions& opt,
                             const Eigen::Vector3d& x0, const char* name) {
    expect_invalid([&] { (void)FastSlam(r, q, opt, x0); }, name);
  };
  const Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
  bad_model(-Eigen::Matrix3d::Identity(), kMeasurementNoise, o, x0, "motion_noise");
  bad_model(Eigen::Matrix4d::Identity(), kMeasurementNoise, o, x0, "motion_noise");
  bad_model(kMotionNoise, Eigen::Matrix2d::Zero(), o, x0, "measurement_noise");
  Eigen::MatrixXd nan_q = kMeasurementNoise;
  nan_q(0, 0) = NAN;
  bad_model(kMotionNoise, nan_q, o, x0, "measurement_noise");
  FastSlamOptions signatures = o;
  signatures.use_signatures = true;
  bad_model(kMotionNoise, kMeasurementNoise, signatures, x0, "measurement_noise");
  bad_model(kMotionNoise, kMeasurementNoise, o, Eigen::Vector3d(INFINITY, 0.0, 0.0), "initial_pose");

  const World w = make_world(10, 6);
  FastSlam f = filter(options(8, 2));
  drive(f, w, false);
  const FastSlam saved = f;
  RowMatrixXd z(1, 2);
  z << -1.0, 0.0;
  expect_invalid([&] { f.update(z, {1}); }, "z");
  z << NAN, 0.0;
  expect_invalid([&] { f.update_unknown(z); }, "z");
  z << 1.0, 0.0;
  expect_invalid([&] { f.update(z, {-1}); }, "ids");
  expect_invalid([&] { f.update(z, {1, 2}); }, "ids");
  expect_invalid([&] { f.update(RowMatrixXd::Ones(1, 3), {1}); }, "z");
  expect_invalid([&] { f.update_unknown(z, 0.0); }, "p_new");
  expect_invalid([&] { f.predict(1.0, 0.0, 0.0); }, "dt");
  expect_invalid([&] { f.predict(NAN, 0.0, 1.0); }, "v");
  expect_invalid([&] { f.predict(2e9, 0.0, 1.0); }, "v");
  expect_invalid([&] { f.predict_odometry(Eigen::Vector3d(1.0, 0.0, NAN), Eigen::Matrix3d::Zero()); }, "delta");
  expect_invalid([&] { f.predict_odometry(Eigen::Vector3d::Zero(), -Eigen::Matrix3d::Identity()); }, "noise");
  expect_invalid([&] { f.particle(8); }, "index");
  EXPECT_TRUE(same_state(f, saved));
}

TEST(FastSlam, OutlierMixtureWeightsAndSkipsTheLandmark) {
  // One particle that never moves: a landmark first seen from the origin has Sigma = H^-1 Q H^-T,
  // so a second sighting from the same pose has Q_j = H Sigma H^T + Q = 2 Q exactly.
  const Eigen::Matrix2d q = Eigen::Vector2d(0.01, 0.001).asDiagonal();
  constexpr double kDensity = 0.05;  // 1 / (m rad)
  // Rounding of the 2x2 products against the closed form: far below any weight that matters.
  constexpr double kTolerance = 1e-12;
  for (const double range : {5.02, 8.0}) {
    FastSlamOptions o;
    o.num_particles = 1;
    o.outlier_density = kDensity;
    FastSlam f(Eigen::Matrix3d::Zero(), q, o);
    RowMatrixXd z(1, 2);
    z << 5.0, 0.0;
    f.update(z, {0});
    const Landmark first = f.landmarks(0)[0];
    z << range, 0.01;
    f.update(z, {0});
    const Eigen::Vector2d nu(range - 5.0, 0.01);
    const Eigen::Matrix2d s = 2.0 * q;
    const double gauss = std::exp(-0.5 * nu.dot(s.inverse() * nu)) / (2.0 * M_PI * std::sqrt(s.determinant()));
    EXPECT_NEAR(f.last_log_likelihoods()[0], std::log(gauss + kDensity), kTolerance) << range;
    const Landmark after = f.landmarks(0)[0];
    if (gauss < kDensity) {
      EXPECT_TRUE(after.mean == first.mean && after.cov == first.cov) << range;
    } else {
      EXPECT_FALSE(after.mean == first.mean) << range;
    }
  }
  FastSlamOptions o = options(4, 1);
  o.outlier_density = -1.0;
  expect_invalid([&] { (void)filter(o); }, "outlier_density");
  o.outlier_density = NAN;
  expect_invalid([&] { (void)filter(o); }, "outlier_density");
}

// The free list hands a thread back the block it freed last (not under AddressSanitizer, which
// must see every free); the sharded counter sums what any number of threads added.
TEST(NodePool, ReusesTheLastFreedBlockOfTheThread) {
  struct Blob {
    double d[8];
  };
  void* a = NodePool<Blob>::allocate();
  void* b = NodePool<Blob>::allocate();
  NodePool<Blob>::release(a);
  void* c = NodePool<Blob>::allocate();
#if PROBSLAM_NODE_POOL_ENABLED
  EXPECT_EQ(c, a);
#endif
  std::thread other([&] {
    NodePool<Blob>::release(b);  // freed on another thread: joins that thread's list
    void* d = NodePool<Blob>::allocate();
#if PROBSLAM_NODE_POOL_ENABLED
    EXPECT_EQ(d, b);
#endif
    NodePool<Blob>::release(d);
  });
  other.join();
  NodePool<Blob>::release(c);
}

TEST(ShardedCounter, SumsAcrossThreads) {
  ShardedCounter counter;
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < 10000; ++i) counter.add(t % 2 ? 2 : -1);
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(counter.load(), 4 * 10000 * 2 - 4 * 10000);
}
