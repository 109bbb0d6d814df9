#pragma once
// The 3-D occupancy grid: ch. 9.2's grid in three dimensions (the book notes the cost grows
// with the volume), stored sparsely in hashed blocks of voxels and updated with OctoMap 1.9's
// insertPointCloud rules so that its voxels agree with an octomap::OcTree's value for value.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "probslam/core/object_mutex.hpp"
#include "probslam/grid/occupancy_grid_2d.hpp"
#include "probslam/grid/ray_traversal.hpp"

namespace probslam {

class StateWriter;
class StateReader;
template <bool Concurrent>
class VoxelStoreT;
template <int Dim, typename Real>
struct ScanSegments;
class WorkerPool;

/// OctoMap's voxel addressing at full depth: key = (int)floor(coord / res) + 32768 per axis,
/// valid in [0, 65536); a key's centre is (key - 32768 + 0.5) * res. Keys outside the valid
/// range saturate at +-kKeyBound + 32768 (OctoMap's cast would be undefined beyond int range),
/// NaN gives an invalid key too; so a ray walk stays consistent outside the range.
struct OctreeLattice {
  static constexpr int kKeyOffset = 32768;
  static constexpr int kKeyLimit = 65536;
  double res = 0.1, inv_res = 10.0;

  int key(int /*axis*/, double coord) const { return saturated_key(inv_res * coord) + kKeyOffset; }
  double key_to_coord(int /*axis*/, int key) const { return (static_cast<double>(key - kKeyOffset) + 0.5) * res; }
  double resolution() const { return res; }
  static bool valid(const CellKey<3>& k) {
    return static_cast<unsigned>(k[0]) < kKeyLimit && static_cast<unsigned>(k[1]) < kKeyLimit &&
           static_cast<unsigned>(k[2]) < kKeyLimit;
  }
  static KeyBox<3> key_box() { return {{0, 0, 0}, {kKeyLimit, kKeyLimit, kKeyLimit}}; }
};

/// Sensor model and log-odds bounds of the 3-D grid, as probabilities (OctoMap's defaults).
struct OccupancyParams3D {
  double p_hit = 0.7;
  double p_miss = 0.4;
  double clamp_min = 0.1192;
  double clamp_max = 0.971;
  double occupancy_threshold = 0.5;
};

/// What one insert_point_cloud did with its points.
struct InsertStats3D {
  std::size_t points = 0;          // points given
  std::size_t skipped_nonfinite = 0;  // NaN or inf coordinates: left out entirely
  std::size_t out_of_bounds = 0;   // end (or max-range cut) voxel outside OctoMap's key range
  std::size_t max_range_cut = 0;   // points beyond max_range: they only clear, up to max_range
  std::size_t voxels_updated = 0;  // voxels changed by this scan (each at most once)
};

class OccupancyGrid3D {
 public:
  /// Lock it around every call when several threads share this object (core/object_mutex.hpp).
  std::mutex& mutex() const noexcept { return mutex_.get(); }

  /// insert_point_cloud refuses more worker threads: more than any machine this runs on has
  /// cores only adds thread stacks and contention, so a larger count is a mistake.
  static constexpr int kMaxThreads = 256;

  /// Voxels per block edge is 2^kBlockBits; blocks are allocated when a ray first reaches them.
  static constexpr int kBlockBits = 3;
  static constexpr int kBlockSide = 1 << kBlockBits;
  static constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

  /// resolution (m per voxel edge). Log-odds are float, as in OctoMap: hit logit(p_hit), miss
  /// logit(p_miss), clamped to [logit(clamp_min), logit(clamp_max)] after every update.
  explicit OccupancyGrid3D(double resolution, const OccupancyParams3D& params = {});
  OccupancyGrid3D(const OccupancyGrid3D&) = delete;
  OccupancyGrid3D& operator=(const OccupancyGrid3D&) = delete;
  OccupancyGrid3D(OccupancyGrid3D&&) noexcept;
  OccupancyGrid3D& operator=(OccupancyGrid3D&&) noexcept;
  ~OccupancyGrid3D();

  double resolution() const { return lattice_.res; }
  const OctreeLattice& lattice() const { return lattice_; }
  const OccupancyParams3D& params() const { return params_; }
  float hit_log_odds() const { return hit_; }
  float miss_log_odds() const { return miss_; }
  float clamp_min_log_odds() const { return lo_; }
  float clamp_max_log_odds() const { return hi_; }
  float occupancy_log_odds() const { return occ_; }

  /// One scan with OctoMap 1.9.7's OcTree::insertPointCloud rules (lazy_eval and discretize
  /// off): points (n x 3, float, as OctoMap's point3d) and origin in the map frame. A point
  /// within max_range of the origin (or any point if max_range < 0) clears the voxels its ray
  /// crosses and hits its own; a farther one clears the ray cut at max_range and hits nothing.
  /// Each voxel changes at most once per scan, hit beating miss. Non-finite points are skipped
  /// and counted. With threads > 1 (at most kMaxThreads) the rays are walked concurrently; the
  /// result is identical. All worker threads are started before the map changes: when one cannot
  /// be, std::system_error is thrown and the map is unchanged. (std::bad_alloc midway leaves the
  /// scan partly applied, with the map consistent.)
  InsertStats3D insert_point_cloud(const float* xyz, std::size_t n, const float origin[3], double max_range = -1.0,
                                   int threads = 1);
  /// The same for double coordinates, rounded to float first.
  InsertStats3D insert_point_cloud(const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& points,
                                   const Eigen::Vector3d& origin, double max_range = -1.0, int threads = 1);

  /// Voxel key of a point (OctoMap's coordToKey); invalid keys have a component outside [0, 65536).
  CellKey<3> key_of(double x, double y, double z) const {
    return {lattice_.key(0, x), lattice_.key(1, y), lattice_.key(2, z)};
  }
  Eigen::Vector3d key_center(const CellKey<3>& k) const {
    return {lattice_.key_to_coord(0, k[0]), lattice_.key_to_coord(1, k[1]), lattice_.key_to_coord(2, k[2])};
  }
  /// Log-odds of a voxel, NaN when unknown (never observed).
  float log_odds_at_key(const CellKey<3>& key) const;
  float log_odds_at(double x, double y, double z) const { return log_odds_at_key(key_of(x, y, z)); }
  /// Known and at or above the occupancy threshold (OctoMap's isNodeOccupied).
  bool is_occupied(double x, double y, double z) const { return log_odds_at(x, y, z) >= occ_; }
  /// Sets a voxel's log-odds (clamped); NaN makes it unknown again.
  void set_log_odds(const CellKey<3>& key, float value);

  /// The first occupied voxel a ray from origin along direction meets within max_range (m),
  /// the origin's voxel included; unknown voxels are passed through. Returns its centre. The
  /// walk is clipped to the key range before it starts: it costs at most the range's size
  /// whatever max_range is, and an origin outside the range is walked from where it enters.
  std::optional<Eigen::Vector3d> cast_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                          double max_range) const;

  /// Calls fn(const CellKey<3>&, float log_odds) for every known voxel (block order).
  template <class Fn>
  void for_each_known(Fn&& fn) const {
    for (std::size_t b = 0; b < block_keys_.size(); ++b) {
      if (known_[b] == 0) continue;
      const CellKey<3> base = block_base(block_keys_[b]);
      const float* v = block_values(b);
      for (int i = 0; i < kBlockVoxels; ++i) {
        if (v[i] != v[i]) continue;  // NaN: unknown
        fn(CellKey<3>{base[0] + (i & (kBlockSide - 1)), base[1] + ((i >> kBlockBits) & (kBlockSide - 1)),
                      base[2] + (i >> (2 * kBlockBits))},
           v[i]);
      }
    }
  }

  std::size_t num_known_voxels() const;
  std::size_t num_occupied_voxels() const;
  std::size_t num_blocks() const { return block_keys_.size(); }
  /// Bytes held by the map (voxel blocks, their bookkeeping and the block hash table).
  std::size_t memory_bytes() const;
  void clear();

  /// Occupancy seen from above: an OccupancyGrid2D on the same x-y lattice covering the known
  /// voxels whose centres lie in [z_min, z_max], each cell holding the largest log-odds of its
  /// column (eq. 9.9's pessimistic fusion); columns with no known voxel keep the prior 0.
  /// Refused (std::invalid_argument naming OccupancyGrid2D.max_cells) before anything is
  /// allocated when the covered area has more cells than OccupancyGrid2D::kMaxCells.
  OccupancyGrid2D project_2d(double z_min, double z_max) const;

  /// Saves the resolution, the sensor parameters and every allocated block of voxels (their
  /// float log-odds, NaN for unknown) in block order, bit for bit (docs/file_format.md): a
  /// loaded grid holds the same voxels in the same blocks, so it iterates and updates as this
  /// one would. The hash table is rebuilt, not saved (it only finds blocks). Load refuses a
  /// damaged file (std::invalid_argument naming the path): a block key outside the key range or
  /// given twice, a voxel's log-odds outside the clamp bounds.
  static constexpr const char* kStateTag = "OccupancyGrid3D";
  void save(const std::string& path) const;
  static OccupancyGrid3D load(const std::string& path);
  void write_state(StateWriter& w) const;
  static OccupancyGrid3D read_state(StateReader& r);

 private:
  template <bool Concurrent>
  friend class VoxelStoreT;
  static constexpr int kWordsPerBlock = kBlockVoxels >= 64 ? kBlockVoxels / 64 : 1;
  static constexpr int kBlocksPerChunk = 64;

  static std::uint64_t pack(const CellKey<3>& k) {
    return static_cast<std::uint64_t>(k[0] >> kBlockBits) | (static_cast<std::uint64_t>(k[1] >> kBlockBits) << 16) |
           (static_cast<std::uint64_t>(k[2] >> kBlockBits) << 32);
  }
  static CellKey<3> block_base(std::uint64_t packed) {
    return {static_cast<int>(packed & 0xffff) << kBlockBits, static_cast<int>((packed >> 16) & 0xffff) << kBlockBits,
            static_cast<int>((packed >> 32) & 0xffff) << kBlockBits};
  }
  static int voxel_index(const CellKey<3>& k) {
    constexpr int m = kBlockSide - 1;
    return (k[0] & m) | ((k[1] & m) << kBlockBits) | ((k[2] & m) << (2 * kBlockBits));
  }
  float* block_values(std::size_t b) { return chunks_[b / kBlocksPerChunk].get() + (b % kBlocksPerChunk) * kBlockVoxels; }
  const float* block_values(std::size_t b) const {
    return chunks_[b / kBlocksPerChunk].get() + (b % kBlocksPerChunk) * kBlockVoxels;
  }
  /// Index of the block with this packed key, or -1.
  std::int64_t find_block(std::uint64_t packed) const;
  std::size_t find_or_create_block(std::uint64_t packed);
  void grow_table();
  /// The "changed in this scan" words of these blocks, in their order (kWordsPerBlock each).
  std::vector<std::uint64_t> changed_words(const std::vector<std::uint32_t>& blocks) const;
  /// The miss update of every voxel a scan's ray walks claimed in these blocks: their changed
  /// bits but those in hit_words (the words of the first blocks as the hits left them). Returns
  /// the number of voxels updated.
  std::size_t apply_claimed_misses(const std::vector<std::uint32_t>& touched,
                                   const std::vector<std::uint64_t>& hit_words);
  /// Clears the per-scan "changed" bits of the blocks a scan touched.
  void end_scan(const std::vector<std::uint32_t>& touched);
  /// Ends a scan (end_scan) when it goes out of scope, on an exception too: marks left set would
  /// make the next scan skip those voxels.
  class ScanEnd {
   public:
    ScanEnd(OccupancyGrid3D& grid, const std::vector<std::uint32_t>& touched) : grid_(grid), touched_(touched) {}
    ScanEnd(const ScanEnd&) = delete;
    ScanEnd& operator=(const ScanEnd&) = delete;
    ~ScanEnd() { grid_.end_scan(touched_); }

   private:
    OccupancyGrid3D& grid_;
    const std::vector<std::uint32_t>& touched_;
  };
  /// The multi-threaded half of insert_point_cloud: walks the scan on the pool's threads.
  std::size_t insert_concurrently(WorkerPool& pool, const ScanSegments<3, float>& scan);

  OctreeLattice lattice_;
  OccupancyParams3D params_;
  float hit_ = 0, miss_ = 0, lo_ = 0, hi_ = 0, occ_ = 0;

  std::vector<std::unique_ptr<float[]>> chunks_;  // voxel log-odds, kBlocksPerChunk blocks each
  std::vector<std::uint64_t> block_keys_;         // packed block coordinates, per block
  std::vector<std::uint32_t> known_;              // known voxels per block
  std::vector<std::uint64_t> changed_;            // kWordsPerBlock bits per block: changed this scan
  std::vector<std::uint8_t> listed_;              // block is in this scan's touched list
  // Open-addressing hash table: slot holds packed key + 1 (0 = empty) and the block index.
  std::vector<std::uint64_t> table_keys_;
  std::vector<std::uint32_t> table_blocks_;
  ObjectMutex mutex_;
};

}  // namespace probslam
