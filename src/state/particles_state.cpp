// The particle filters' shared pieces as state (docs/file_format.md): random streams, pose
// paths and landmark maps.
#include <cmath>

#include "probslam/core/state_file.hpp"
#include "probslam/fastslam/landmark_tree.hpp"
#include "probslam/fastslam/particles.hpp"

namespace probslam {

void ParticleRng::write_state(StateWriter& w) const {
  for (std::uint64_t s : s_) w.u64(s);
  w.f64(spare_);
  w.boolean(has_spare_);
}

ParticleRng ParticleRng::read_state(StateReader& r) {
  ParticleRng rng;
  for (std::uint64_t& s : rng.s_) s = r.u64();
  rng.spare_ = r.f64();
  rng.has_spare_ = r.boolean();
  // xoshiro's all-zero state is a fixed point no seeding reaches.
  if (rng.s_[0] == 0 && rng.s_[1] == 0 && rng.s_[2] == 0 && rng.s_[3] == 0) r.fail("a random stream's state is zero");
  return rng;
}

void PosePath::write_state(StateWriter& w) const {
  const Poses2 p = poses();
  w.count(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index k = 0; k < p.rows(); ++k)
    for (int c = 0; c < 3; ++c) w.f64(p(k, c));
}

PosePath PosePath::read_state(StateReader& r) {
  const std::size_t n = r.count(24);
  PosePath path;
  for (std::size_t k = 0; k < n; ++k) {
    Eigen::Vector3d pose;
    for (int c = 0; c < 3; ++c) pose[c] = r.f64();
    if (!pose.allFinite()) r.fail("a path pose is not finite");
    path.push(pose);
  }
  return path;
}

void LandmarkMap::write_state(StateWriter& w) const {
  w.f64(cell_);
  w.count(size());
  for_each([&](const Landmark& lm) {
    w.i64(lm.id);
    w.f64(lm.mean.x());
    w.f64(lm.mean.y());
    w.f64(lm.cov(0, 0));
    w.f64(lm.cov(1, 0));
    w.f64(lm.cov(0, 1));
    w.f64(lm.cov(1, 1));
    w.f64(lm.existence);
    w.f64(lm.signature);
    w.f64(lm.signature_var);
    w.i32(lm.sightings);
    w.i64(lm.last_seen);
  });
}

LandmarkMap LandmarkMap::read_state(StateReader& r) {
  const double cell = r.f64();
  if (!(std::isfinite(cell) && cell > 0.0)) r.fail("a landmark map's cell size is not finite and > 0");
  LandmarkMap map(cell);
  const std::size_t n = r.count(92);
  for (std::size_t k = 0; k < n; ++k) {
    Landmark lm;
    lm.id = static_cast<long>(r.i64());
    lm.mean.x() = r.f64();
    lm.mean.y() = r.f64();
    lm.cov(0, 0) = r.f64();
    lm.cov(1, 0) = r.f64();
    lm.cov(0, 1) = r.f64();
    lm.cov(1, 1) = r.f64();
    lm.existence = r.f64();
    lm.signature = r.f64();
    lm.signature_var = r.f64();
    lm.sightings = r.i32();
    lm.last_seen = static_cast<long>(r.i64());
    if (lm.sightings < 1) r.fail("landmark " + std::to_string(lm.id) + " has fewer than one sighting");
    if (!lm.mean.allFinite() || !lm.cov.allFinite() || !std::isfinite(lm.existence) || !std::isfinite(lm.signature) ||
        !std::isfinite(lm.signature_var))
      r.fail("landmark " + std::to_string(lm.id) + " holds a value that is not finite");
    if (map.find(lm.id)) r.fail("landmark id " + std::to_string(lm.id) + " is repeated in one map");
    map.put(lm);
  }
  return map;
}

}  // namespace probslam
