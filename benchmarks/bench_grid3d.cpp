// Insertion speed and memory of OccupancyGrid3D against octomap::OcTree::insertPointCloud on the
// same simulated lidar clouds. One implementation per process, so that peak RSS is its own;
// bench_grid3d.py runs the combinations and writes the table.
//
//   bench_grid3d --impl ours|octomap --res 0.1 [--scans 100] [--threads 1] [--max-range 20]
//
// Prints one line of key=value pairs.
#include <octomap/OcTree.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "probslam/grid/occupancy_grid_3d.hpp"

namespace {

constexpr double kPi = 3.14159265358979323846;

// The courtyard: 60 x 60 m enclosed by 12 m facades, with a fountain, pillars and parked cars.
struct Box {
  double lo[3], hi[3];
};

std::vector<Box> courtyard_obstacles() {
  std::vector<Box> boxes;
  boxes.push_back({{-2.0, -2.0, 0.0}, {2.0, 2.0, 1.0}});  // fountain
  for (int i = 0; i < 8; ++i) {                           // arcade pillars along two facades
    const double x = -21.0 + 6.0 * i;
    boxes.push_back({{x - 0.4, 26.0, 0.0}, {x + 0.4, 26.8, 5.0}});
    boxes.push_back({{-26.8, x - 0.4, 0.0}, {-26.0, x + 0.4, 5.0}});
  }
  const double cars[5][2] = {{8.0, -20.0}, {14.0, -20.5}, {20.0, -19.8}, {-15.0, 18.0}, {22.0, 10.0}};
  for (const auto& c : cars) boxes.push_back({{c[0] - 2.25, c[1] - 0.9, 0.0}, {c[0] + 2.25, c[1] + 0.9, 1.5}});
  boxes.push_back({{-10.0, -12.0, 0.0}, {-6.0, -8.0, 3.0}});  // a kiosk
  return boxes;
}

// Entry distance of a ray into a box (slab method), or +inf.
double hit_box(const Box& b, const double o[3], const double d[3]) {
  double t0 = 0.0, t1 = 1e30;
  for (int a = 0; a < 3; ++a) {
    if (std::fabs(d[a]) < 1e-12) {
      if (o[a] < b.lo[a] || o[a] > b.hi[a]) return INFINITY;
      continue;
    }
    double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return INFINITY;
  }
  return t0 > 0.0 ? t0 : INFINITY;
}

/// A 64-beam lidar (HDL-64E-like: +2 to -24.8 deg, 1563 azimuths, ~100 k returns) at 1.8 m on a
/// robot circling the courtyard; returns with 1 cm range noise, none for beams into the sky.
void simulate_scan(int index, const std::vector<Box>& boxes, std::vector<float>& xyz, float origin[3]) {
  constexpr int kBeams = 64, kAzimuths = 1563;
  const double a = 0.05 * index;  // 0.6 m along a 12 m circle per scan
  const double o[3] = {12.0 * std::cos(a), 12.0 * std::sin(a), 1.8};
  for (int i = 0; i < 3; ++i) origin[i] = static_cast<float>(o[i]);
  std::mt19937 rng(1000 + index);
  std::normal_distribution<double> noise(0.0, 0.01);
  xyz.clear();
  for (int b = 0; b < kBeams; ++b) {
    const double elev = (2.0 - 26.8 * b / (kBeams - 1)) * kPi / 180.0;
    for (int k = 0; k < kAzimuths; ++k) {
      const double az = 2.0 * kPi * k / kAzimuths + a;
      const double d[3] = {std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), std::sin(elev)};
      double t = INFINITY;
      if (d[2] < 0) t = -o[2] / d[2];  // ground
      for (int ax = 0; ax < 2; ++ax)   // facades at +-30 m, 12 m high
        if (std::fabs(d[ax]) > 1e-12) {
          const double tw = ((d[ax] > 0 ? 30.0 : -30.0) - o[ax]) / d[ax];
          if (o[2] + tw * d[2] <= 12.0) t = std::min(t, tw);
        }
      for (const Box& box : boxes) t = std::min(t, hit_box(box, o, d));
      if (!std::isfinite(t)) continue;  // into the sky: no return
      t += noise(rng);
      for (int i = 0; i < 3; ++i) xyz.push_back(static_cast<float>(o[i] + t * d[i]));
    }
  }
}

// This process's peak resident set (VmHWM; getrusage's ru_maxrss would carry over the parent's
// peak across fork and exec).
long peak_rss_kb() {
  FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return -1;
  char line[256];
  long kb = -1;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmHWM: %ld kB", &kb) == 1) break;
  std::fclose(f);
  return kb;
}

// Processor time of this process (all threads): on a shared machine wall time also counts the
// time other processes held the cores.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Order-independent fingerprint of a voxel map: both implementations must print the same.
std::uint64_t mix(int x, int y, int z, float l) {
  std::uint32_t bits;
  std::memcpy(&bits, &l, 4);
  std::uint64_t h = (static_cast<std::uint64_t>(x) << 32) ^ (static_cast<std::uint64_t>(y) << 16) ^ z;
  h = (h ^ bits) * 0x9E3779B97F4A7C15ull;
  return h ^ (h >> 29);
}

}  // namespace

int main(int argc, char** argv) {
  std::string impl = "ours";
  double res = 0.1, max_range = 20.0;
  int scans = 100, threads = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--impl") impl = v;
    else if (k == "--res") res = std::stod(v);
    else if (k == "--scans") scans = std::stoi(v);
    else if (k == "--threads") threads = std::stoi(v);
    else if (k == "--max-range") max_range = std::stod(v);
    else {
      std::fprintf(stderr, "unknown option %s\n", k.c_str());
      return 2;
    }
  }
  const std::vector<Box> boxes = courtyard_obstacles();
  std::vector<float> xyz;
  xyz.reserve(3 * 110000);
  float origin[3];
  const long rss_before = peak_rss_kb();
  double seconds = 0.0, cpu = 0.0;
  std::size_t points = 0, map_bytes = 0, voxels = 0;
  std::uint64_t fingerprint = 0;
  using Clock = std::chrono::steady_clock;

  if (impl == "ours") {
    probslam::OccupancyGrid3D grid(res);
    for (int s = 0; s < scans; ++s) {
      simulate_scan(s, boxes, xyz, origin);
      points += xyz.size() / 3;
      const auto t0 = Clock::now();
      const double c0 = cpu_seconds();
      grid.insert_point_cloud(xyz.data(), xyz.size() / 3, origin, max_range, threads);
      cpu += cpu_seconds() - c0;
      seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    }
    map_bytes = grid.memory_bytes();
    voxels = grid.num_known_voxels();
    grid.for_each_known([&](const probslam::CellKey<3>& k, float l) { fingerprint += mix(k[0], k[1], k[2], l); });
  } else if (impl == "octomap") {
    octomap::OcTree tree(res);
    octomap::Pointcloud cloud;
    for (int s = 0; s < scans; ++s) {
      simulate_scan(s, boxes, xyz, origin);
      points += xyz.size() / 3;
      cloud.clear();
      cloud.reserve(xyz.size() / 3);
      for (std::size_t i = 0; i < xyz.size(); i += 3) cloud.push_back(xyz[i], xyz[i + 1], xyz[i + 2]);
      const auto t0 = Clock::now();
      const double c0 = cpu_seconds();
      tree.insertPointCloud(cloud, octomap::point3d(origin[0], origin[1], origin[2]), max_range, false, false);
      cpu += cpu_seconds() - c0;
      seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    }
    map_bytes = tree.memoryUsage();
    const unsigned depth = tree.getTreeDepth();
    for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
      const int side = 1 << (depth - it.getDepth());
      const int mask = ~(side - 1);
      const octomap::OcTreeKey k = it.getKey();
      const float l = it->getLogOdds();
      for (int z = 0; z < side; ++z)
        for (int y = 0; y < side; ++y)
          for (int x = 0; x < side; ++x) fingerprint += mix((k[0] & mask) + x, (k[1] & mask) + y, (k[2] & mask) + z, l);
      voxels += static_cast<std::size_t>(side) * side * side;
    }
  } else {
    std::fprintf(stderr, "--impl must be ours or octomap\n");
    return 2;
  }
  std::printf("impl=%s res=%g threads=%d scans=%d points=%zu seconds=%.3f points_per_s=%.0f cpu_seconds=%.3f points_per_cpu_s=%.0f map_bytes=%zu "
              "voxels=%zu rss_before_kb=%ld peak_rss_kb=%ld fingerprint=%016llx\n",
              impl.c_str(), res, threads, scans, points, seconds, points / seconds, cpu, points / cpu, map_bytes, voxels, rss_before,
              peak_rss_kb(), static_cast<unsigned long long>(fingerprint));
  return 0;
}
