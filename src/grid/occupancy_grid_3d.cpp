#include "probslam/grid/occupancy_grid_3d.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>

#include "probslam/core/check.hpp"
#include "probslam/grid/log_odds.hpp"
#include "probslam/grid/scan_update.hpp"
#include "probslam/core/worker_pool.hpp"

namespace probslam {
namespace {

constexpr std::size_t kInitialTableSlots = 1024;  // power of two
// Below this many rays per thread, threads cost more than they save.
constexpr std::size_t kMinRaysPerThread = 512;
// cast_ray cuts a range beyond this many times the farthest distance to the key range (so that
// its end stays finite); rays up to it are walked exactly as given.
constexpr double kRayCutSlack = 1024.0;
// Rays are grouped by azimuth into this many sectors so that each thread walks its own wedge
// of space: threads walking neighbouring rays would fight over the same cache lines.
constexpr int kAzimuthSectors = 1024;

// A double as OctoMap's float point coordinate. A finite value beyond float range becomes
// +-FLT_MAX (a far point, outside the key range) instead of undefined behaviour; NaN and inf
// stay as they are (skipped and counted as non-finite).
float to_float(double v) {
  constexpr double kFloatMax = std::numeric_limits<float>::max();
  return static_cast<float>(std::isfinite(v) ? std::min(std::max(v, -kFloatMax), kFloatMax) : v);
}

// OctoMap stores its probabilities as float log-odds: logodds(p) = (float) log(p / (1 - p)).
float float_logit(double p) { return static_cast<float>(logit(p)); }

std::size_t hash_slot(std::uint64_t packed, std::size_t mask) {
  return static_cast<std::size_t>((packed * 0x9E3779B97F4A7C15ull) >> 29) & mask;
}

}  // namespace

/// The grid as a scan's update sees it: OctoMap's key range, voxels that change once per scan.
/// Hits are applied as they come; misses only claim their voxels (a bit each), and
/// OccupancyGrid3D::apply_claimed_misses updates the claimed voxels once every ray is walked:
/// a voxel hit or claimed once is left alone by the rest of the scan, as in OctoMap, where a
/// voxel both hit and crossed counts as hit. Serial flavour: creates blocks on demand.
/// Concurrent flavour: never creates a block (the block table is read-only while several walk),
/// claims voxels with atomic bit operations, and reports rays that reached a missing block so
/// that the caller re-walks them serially.
template <bool Concurrent>
class VoxelStoreT {
 public:
  VoxelStoreT(OccupancyGrid3D& grid, std::vector<std::uint32_t>& touched) : g_(grid), touched_(touched) {}

  bool contains(const CellKey<3>& k) const { return OctreeLattice::valid(k); }
  KeyBox<3> box() const { return OctreeLattice::key_box(); }

  /// A hit updates the voxel now; a miss claims it (see update_in_block).
  bool update_once(const CellKey<3>& k, bool hit) {
    const std::uint64_t packed = OccupancyGrid3D::pack(k);
    if (packed != cached_) select(packed);
    return update_in_block(k, hit);
  }

 private:
  /// update_once(k, false) for miss_ray's keys, packed 16 bits per axis: the block key and the
  /// voxel index come out of the packed key with a few shifts and masks.
  bool claim(std::uint64_t key) {
    constexpr int b = OccupancyGrid3D::kBlockBits;
    constexpr std::uint64_t field = (std::uint64_t{1} << (16 - b)) - 1;  // a block coordinate
    const std::uint64_t packed = (key >> b) & (field | (field << 16) | (field << 32));
    if (packed != cached_) select(packed);
    constexpr std::uint64_t m = OccupancyGrid3D::kBlockSide - 1;
    const int x = static_cast<int>(key & m), y = static_cast<int>((key >> 16) & m);
    const int z = static_cast<int>((key >> 32) & m);
    return update_in_block(CellKey<3>{x, y, z}, false);
  }

  bool update_in_block(const CellKey<3>& k, bool hit) {
    if (Concurrent && values_ == nullptr) {
      missing_ = true;
      return false;
    }
    const int v = OccupancyGrid3D::voxel_index(k);
    std::uint64_t* word = changed_ + (v >> 6);
    const std::uint64_t bit = std::uint64_t{1} << (v & 63);
    if constexpr (Concurrent) {
      // Most voxels near the sensor are crossed by many rays: a plain look first spares the
      // locked read-modify-write for those already claimed.
      if (__atomic_load_n(word, __ATOMIC_RELAXED) & bit) return false;
      if (__atomic_fetch_or(word, bit, __ATOMIC_RELAXED) & bit) return false;
    } else {
      if (*word & bit) return false;
      *word |= bit;
    }
    // A miss only claims the voxel: the claimed voxels' values are updated after the walk, block
    // by block (apply_claimed_misses), so that the walk reads one bit per voxel and not its value
    // (the values of a scan's voxels are far more than the cache holds).
    if (!hit) return true;
    float& l = values_[v];
    float x = l;
    if (x != x) {  // unknown: OctoMap creates the node with log-odds 0
      x = 0.0f;
      if constexpr (Concurrent) __atomic_fetch_add(known_, 1u, __ATOMIC_RELAXED);
      else ++*known_;
    }
    x += g_.hit_;
    if (x < g_.lo_) x = g_.lo_;
    else if (x > g_.hi_) x = g_.hi_;
    l = x;
    return true;
  }

 public:
  /// The miss half of one ray (apply_misses for a single segment): every voxel the ray from
  /// origin to end crosses, origin's included and end's excluded, is claimed for the miss update
  /// unless it changed already in this scan (OccupancyGrid3D::apply_claimed_misses updates the
  /// claimed voxels). Returns the number of voxels claimed.
  ///
  /// Where both ends lie in the key range (every ray of a lidar scan but the rare one leaving
  /// the 6.5 km range), the walk is walk_ray's, with its arithmetic step for step (so the same
  /// voxels, OctoMap's), specialised: the axis to step is selected without a branch, the key
  /// range is checked per step rather than through a box, and the keys are claimed in batches,
  /// their block looked up only when it changes. Other rays take walk_ray_in_box.
  std::size_t miss_ray(const float* origin, const float* end) {
    const OctreeLattice& lat = g_.lattice_;
    int k[3], key_end[3];
    for (int i = 0; i < 3; ++i) {
      k[i] = lat.key(i, origin[i]);
      key_end[i] = lat.key(i, end[i]);
    }
    if (!OctreeLattice::valid({k[0], k[1], k[2]}) || !OctreeLattice::valid({key_end[0], key_end[1], key_end[2]})) {
      std::size_t updated = 0;
      walk_ray_in_box<3, float>(lat, OctreeLattice::key_box(), origin, end, [&](const CellKey<3>& key) {
        updated += update_once(key, false);
        return true;
      });
      return updated;
    }
    if (k[0] == key_end[0] && k[1] == key_end[1] && k[2] == key_end[2]) return 0;
    // The origin's voxel: its block is looked up (the last ray may have ended in another).
    std::size_t updated = update_once({k[0], k[1], k[2]}, false);

    // walk_ray's start, operation for operation (float direction and length, double steps).
    const RayStart<3, float> start = ray_start<3>(lat, origin, end, k);
    const int* const step = start.step;
    const double* const t_max = start.t_max;
    const double* const t_delta = start.t_delta;
    const float length = start.length;
    // The walk's state in scalars, stepped in batches into a buffer of voxel keys which is then
    // claimed: a loop without calls keeps the state in registers and selects the axis with
    // conditional moves (a call inside, to the block lookup, made the compiler keep the state
    // in memory; arrays indexed by the axis did too).
    int kx = k[0], ky = k[1], kz = k[2];
    const int ex = key_end[0], ey = key_end[1], ez = key_end[2];
    const int sx = step[0], sy = step[1], sz = step[2];
    double tx = t_max[0], ty = t_max[1], tz = t_max[2];
    const double dx = t_delta[0], dy = t_delta[1], dz = t_delta[2];
    const double limit = length;
    constexpr int kBatch = 256;
    std::uint64_t batch[kBatch];  // keys packed 16 bits per axis (they are in the key range)
    for (bool done = false; !done;) {
      int n = 0;
      while (n < kBatch) {
        // walk_ray's choice: the lowest t_max, ties to the higher axis. Adding 0 leaves the
        // other axes' t_max as they are (DBL_MAX included).
        const bool x_before_y = tx < ty;
        const bool along_z = !((x_before_y ? tx : ty) < tz);
        const bool along_x = x_before_y && !along_z, along_y = !x_before_y && !along_z;
        kx += along_x ? sx : 0;
        ky += along_y ? sy : 0;
        kz += along_z ? sz : 0;
        tx += along_x ? dx : 0.0;
        ty += along_y ? dy : 0.0;
        tz += along_z ? dz : 0.0;
        const double txy = ty < tx ? ty : tx;  // min by value (std::min's references spill)
        if ((kx == ex && ky == ey && kz == ez) || (tz < txy ? tz : txy) > limit) {
          done = true;
          break;
        }
        // Rounding may carry the walk a voxel past the end's key on an axis: the range is checked.
        if (!OctreeLattice::valid({kx, ky, kz})) continue;
        batch[n++] = static_cast<std::uint64_t>(kx) | (static_cast<std::uint64_t>(ky) << 16) |
                     (static_cast<std::uint64_t>(kz) << 32);
      }
      for (int i = 0; i < n; ++i) updated += claim(batch[i]);
    }
    return updated;
  }

  bool missing() const { return missing_; }
  void reset_missing() { missing_ = false; }
  /// Where the concurrent flavour lists the blocks it found missing.
  void record_missing_blocks(std::vector<std::uint64_t>* blocks) { missing_blocks_ = blocks; }

 private:
  void select(std::uint64_t packed) {
    cached_ = packed;
    // The blocks found lately, by their key's low bits: neighbouring rays cross the same blocks,
    // and the hash table is too large to stay in cache (its probes were a tenth of a scan's time).
    const std::size_t slot = (packed & kRecentMask) | (((packed >> 16) & kRecentMask) << kRecentBits) |
                             (((packed >> 32) & kRecentMask) << (2 * kRecentBits));
    std::size_t b;
    if (recent_key_[slot] == packed) {
      b = recent_block_[slot];
    } else if constexpr (Concurrent) {
      const std::int64_t found = g_.find_block(packed);
      if (found < 0) {
        values_ = nullptr;
        if (missing_blocks_ != nullptr) missing_blocks_->push_back(packed);
        return;
      }
      b = static_cast<std::size_t>(found);
    } else {
      b = g_.find_or_create_block(packed);
    }
    recent_key_[slot] = packed;
    recent_block_[slot] = static_cast<std::uint32_t>(b);
    if constexpr (Concurrent) {
      if (__atomic_exchange_n(&g_.listed_[b], std::uint8_t{1}, __ATOMIC_RELAXED) == 0)
        touched_.push_back(static_cast<std::uint32_t>(b));
    } else if (!g_.listed_[b]) {
      g_.listed_[b] = 1;
      touched_.push_back(static_cast<std::uint32_t>(b));
    }
    values_ = g_.block_values(b);
    changed_ = g_.changed_.data() + b * OccupancyGrid3D::kWordsPerBlock;
    known_ = g_.known_.data() + b;
  }

  // Blocks are indices into the grid's arrays, which only grow while a scan is applied (and not
  // at all while the concurrent flavour walks): a remembered index stays valid.
  static constexpr int kRecentBits = 3;  // per axis: the last 8 x 8 x 8 block neighbourhood
  static constexpr std::uint64_t kRecentMask = (1u << kRecentBits) - 1;
  static constexpr std::size_t kRecentSlots = std::size_t{1} << (3 * kRecentBits);

  OccupancyGrid3D& g_;
  std::vector<std::uint32_t>& touched_;
  std::array<std::uint64_t, kRecentSlots> recent_key_ = filled_keys();
  std::array<std::uint32_t, kRecentSlots> recent_block_{};
  static std::array<std::uint64_t, kRecentSlots> filled_keys() {
    std::array<std::uint64_t, kRecentSlots> keys;
    keys.fill(~std::uint64_t{0});  // no packed key (48 bits) has all bits set
    return keys;
  }
  std::uint64_t cached_ = ~std::uint64_t{0};
  float* values_ = nullptr;
  std::uint64_t* changed_ = nullptr;
  std::uint32_t* known_ = nullptr;
  bool missing_ = false;
  std::vector<std::uint64_t>* missing_blocks_ = nullptr;
};

using VoxelStore = VoxelStoreT<false>;
using VoxelLookupStore = VoxelStoreT<true>;

OccupancyGrid3D::OccupancyGrid3D(double resolution, const OccupancyParams3D& params) {
  require_positive(resolution, "resolution");
  // Voxel centres span +-32768 res and keys scale by 1 / res: both must stay finite.
  require(std::isfinite(1.0 / resolution) && std::isfinite(resolution * OctreeLattice::kKeyLimit), "resolution",
          "must have a finite inverse and a finite key range (65536 * resolution)");
  require_probability(params.p_hit, "p_hit");
  require_probability(params.p_miss, "p_miss");
  require(params.p_hit > 0.5, "p_hit", "must be > 0.5 (a hit must raise the occupancy)");
  require(params.p_miss < 0.5, "p_miss", "must be < 0.5 (a miss must lower the occupancy)");
  require_probability(params.clamp_min, "clamp_min");
  require_probability(params.clamp_max, "clamp_max");
  require(params.clamp_min < params.clamp_max, "clamp_min", "must be < clamp_max");
  require_probability(params.occupancy_threshold, "occupancy_threshold");
  lattice_.res = resolution;
  lattice_.inv_res = 1.0 / resolution;  // OctoMap's resolution_factor
  params_ = params;
  hit_ = float_logit(params.p_hit);
  miss_ = float_logit(params.p_miss);
  lo_ = float_logit(params.clamp_min);
  hi_ = float_logit(params.clamp_max);
  occ_ = float_logit(params.occupancy_threshold);
  clear();
}

OccupancyGrid3D::OccupancyGrid3D(OccupancyGrid3D&&) noexcept = default;
OccupancyGrid3D& OccupancyGrid3D::operator=(OccupancyGrid3D&&) noexcept = default;
OccupancyGrid3D::~OccupancyGrid3D() = default;

void OccupancyGrid3D::clear() {
  chunks_.clear();
  block_keys_.clear();
  known_.clear();
  changed_.clear();
  listed_.clear();
  table_keys_.assign(kInitialTableSlots, 0);
  table_blocks_.assign(kInitialTableSlots, 0);
}

std::int64_t OccupancyGrid3D::find_block(std::uint64_t packed) const {
  const std::size_t mask = table_keys_.size() - 1;
  for (std::size_t s = hash_slot(packed, mask);; s = (s + 1) & mask) {
    const std::uint64_t k = table_keys_[s];
    if (k == packed + 1) return table_blocks_[s];
    if (k == 0) return -1;
  }
}

void OccupancyGrid3D::grow_table() {
  const std::size_t slots = table_keys_.size() * 2, mask = slots - 1;
  std::vector<std::uint64_t> keys(slots, 0);
  std::vector<std::uint32_t> blocks(slots, 0);
  for (std::size_t b = 0; b < block_keys_.size(); ++b) {
    std::size_t s = hash_slot(block_keys_[b], mask);
    while (keys[s] != 0) s = (s + 1) & mask;
    keys[s] = block_keys_[b] + 1;
    blocks[s] = static_cast<std::uint32_t>(b);
  }
  table_keys_.swap(keys);
  table_blocks_.swap(blocks);
}

std::size_t OccupancyGrid3D::find_or_create_block(std::uint64_t packed) {
  std::size_t mask = table_keys_.size() - 1;
  std::size_t s = hash_slot(packed, mask);
  for (;; s = (s + 1) & mask) {
    const std::uint64_t k = table_keys_[s];
    if (k == packed + 1) return table_blocks_[s];
    if (k == 0) break;
  }
  const std::size_t b = block_keys_.size();
  if (b % kBlocksPerChunk == 0) {
    chunks_.emplace_back(new float[static_cast<std::size_t>(kBlocksPerChunk) * kBlockVoxels]);
    std::fill_n(chunks_.back().get(), static_cast<std::size_t>(kBlocksPerChunk) * kBlockVoxels,
                std::numeric_limits<float>::quiet_NaN());
  }
  block_keys_.push_back(packed);
  known_.push_back(0);
  changed_.resize(changed_.size() + kWordsPerBlock, 0);
  listed_.push_back(0);
  // Keep the table at most half full so that probe sequences stay short.
  if (2 * block_keys_.size() > table_keys_.size()) {
    grow_table();
  } else {
    table_keys_[s] = packed + 1;
    table_blocks_[s] = static_cast<std::uint32_t>(b);
  }
  return b;
}

void OccupancyGrid3D::end_scan(const std::vector<std::uint32_t>& touched) {
  for (const std::uint32_t b : touched) {
    std::fill_n(changed_.data() + static_cast<std::size_t>(b) * kWordsPerBlock, kWordsPerBlock, 0);
    listed_[b] = 0;
  }
}

std::vector<std::uint64_t> OccupancyGrid3D::changed_words(const std::vector<std::uint32_t>& blocks) const {
  std::vector<std::uint64_t> words(blocks.size() * kWordsPerBlock);
  for (std::size_t j = 0; j < blocks.size(); ++j)
    std::copy_n(changed_.data() + static_cast<std::size_t>(blocks[j]) * kWordsPerBlock, kWordsPerBlock,
                words.data() + j * kWordsPerBlock);
  return words;
}

std::size_t OccupancyGrid3D::apply_claimed_misses(const std::vector<std::uint32_t>& touched,
                                                  const std::vector<std::uint64_t>& hit_words) {
  const std::size_t hit_blocks = hit_words.size() / kWordsPerBlock;
  std::size_t updated = 0;
  for (std::size_t j = 0; j < touched.size(); ++j) {
    const std::size_t b = touched[j];
    float* values = block_values(b);
    const std::uint64_t* changed = changed_.data() + b * kWordsPerBlock;
    std::uint32_t became_known = 0;
    for (int w = 0; w < kWordsPerBlock; ++w) {
      std::uint64_t bits = changed[w] & ~(j < hit_blocks ? hit_words[j * kWordsPerBlock + w] : 0);
      for (; bits != 0; bits &= bits - 1) {
        float& l = values[64 * w + __builtin_ctzll(bits)];
        float x = l;
        if (x != x) {  // unknown: OctoMap creates the node with log-odds 0
          x = 0.0f;
          ++became_known;
        }
        x += miss_;
        if (x < lo_) x = lo_;
        else if (x > hi_) x = hi_;
        l = x;
        ++updated;
      }
    }
    known_[b] += became_known;
  }
  return updated;
}

InsertStats3D OccupancyGrid3D::insert_point_cloud(const float* xyz, std::size_t n, const float origin[3],
                                                  double max_range, int threads) {
  require(std::isfinite(origin[0]) && std::isfinite(origin[1]) && std::isfinite(origin[2]), "origin",
          "must contain only finite values");
  require(!std::isnan(max_range), "max_range", "must not be NaN (negative means unlimited)");
  if (threads < 1 || threads > kMaxThreads)
    throw_invalid_argument("threads", "must be between 1 and " + std::to_string(kMaxThreads) +
                                          " (OccupancyGrid3D::kMaxThreads), got " + std::to_string(threads));
  require(n == 0 || xyz != nullptr, "points", "must not be null");
  InsertStats3D stats;
  stats.points = n;

  // Turn points into segments with computeUpdate's arithmetic: float differences, the norm
  // as sqrt(double(float sum of squares)), the cut end as origin + (d / (float)|d|) * (float)max_range.
  std::vector<float> ends;
  std::vector<std::uint8_t> is_hit;
  ends.reserve(3 * n);
  is_hit.reserve(n);
  const bool cut = max_range >= 0.0;
  const float range_f = static_cast<float>(max_range);
  for (std::size_t i = 0; i < n; ++i) {
    const float* p = xyz + 3 * i;
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) {
      ++stats.skipped_nonfinite;
      continue;
    }
    const float d[3] = {p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]};
    const float norm_sq = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double norm = std::sqrt(static_cast<double>(norm_sq));
    float end[3] = {p[0], p[1], p[2]};
    bool hit = true;
    if (cut && !(norm <= max_range)) {
      ++stats.max_range_cut;
      hit = false;
      const float len = static_cast<float>(norm);  // > 0: the point lies beyond max_range >= 0
      for (int a = 0; a < 3; ++a) end[a] = origin[a] + (d[a] / len) * range_f;
    }
    const CellKey<3> key = key_of(end[0], end[1], end[2]);
    if (!OctreeLattice::valid(key)) {  // OctoMap drops both the ray and the hit
      ++stats.out_of_bounds;
      continue;
    }
    ends.insert(ends.end(), end, end + 3);
    is_hit.push_back(hit);
  }

  const ScanSegments<3, float> scan{origin, ends.data(), is_hit.data(), is_hit.size()};
  const bool origin_valid = OctreeLattice::valid(key_of(origin[0], origin[1], origin[2]));
  const std::size_t workers =
      origin_valid ? std::min<std::size_t>(static_cast<std::size_t>(threads), scan.n / kMinRaysPerThread) : 1;
  if (workers <= 1) {
    std::vector<std::uint32_t> touched;
    VoxelStore store(*this, touched);
    ScanEnd guard(*this, touched);
    stats.voxels_updated = apply_hits(lattice_, store, scan);
    // computeRayKeys refuses a ray whose origin is outside the key range; the hits remain.
    if (origin_valid) {
      const std::vector<std::uint64_t> hit_words = changed_words(touched);
      for (std::size_t i = 0; i < scan.n; ++i) store.miss_ray(origin, scan.ends + 3 * i);
      stats.voxels_updated += apply_claimed_misses(touched, hit_words);
    }
    return stats;
  }
  // Every thread is started before anything changes: a refused thread leaves the map as it was.
  WorkerPool pool(workers);
  stats.voxels_updated = insert_concurrently(pool, scan);
  return stats;
}

std::size_t OccupancyGrid3D::insert_concurrently(WorkerPool& pool, const ScanSegments<3, float>& scan) {
  const std::size_t workers = pool.size();
  const float* origin = scan.origin;
  // Concurrent updates of the existing blocks; an update that needs a missing block is set
  // aside, the missing blocks are created serially and the set-aside work done again. Hits go
  // first, all of them, then the rays. The per-scan result is a union of voxel sets (hit beats
  // miss, one change per voxel), so it does not depend on which thread does what or how often.
  //
  // Rays are walked in azimuth order, each thread over a contiguous range of sectors: threads
  // walking neighbouring rays would fight over the same cache lines.
  std::vector<std::uint32_t> order(scan.n);
  {
    std::vector<std::uint16_t> sector(scan.n);
    std::vector<std::uint32_t> start(kAzimuthSectors + 1, 0);
    for (std::size_t i = 0; i < scan.n; ++i) {
      // A pseudo-angle in [-2, 2], monotonic in the azimuth: cheaper than atan2.
      const double dx = scan.ends[3 * i] - origin[0], dy = scan.ends[3 * i + 1] - origin[1];
      const double r = std::fabs(dx) + std::fabs(dy);
      double p = r > 0.0 ? dy / r : 0.0;
      p = dx >= 0.0 ? p : (dy >= 0.0 ? 2.0 - p : -2.0 - p);
      const int k = static_cast<int>((p + 2.0) * (kAzimuthSectors / 4.0));
      sector[i] = static_cast<std::uint16_t>(std::min(std::max(k, 0), kAzimuthSectors - 1));
      ++start[sector[i] + 1];
    }
    for (int k = 0; k < kAzimuthSectors; ++k) start[k + 1] += start[k];
    for (std::size_t i = 0; i < scan.n; ++i) order[start[sector[i]]++] = static_cast<std::uint32_t>(i);
  }
  std::vector<std::uint32_t> hit_points;
  for (std::size_t i = 0; i < scan.n; ++i)
    if (scan.is_hit[i]) hit_points.push_back(static_cast<std::uint32_t>(i));

  std::vector<std::vector<std::uint32_t>> touched_by(workers), deferred_by(workers);
  std::vector<std::vector<std::uint64_t>> missing_by(workers);
  std::vector<std::size_t> updated_by(workers, 0);
  // Only with every ray walked (or on an exception) may the "changed in this scan" marks go.
  std::vector<std::unique_ptr<ScanEnd>> guards;
  for (auto& t : touched_by) guards.push_back(std::make_unique<ScanEnd>(*this, t));
  // Does updates [share of `items`] on each thread: hits (one point each) or ray walks.
  const auto run = [&](const std::vector<std::uint32_t>& items, bool hits, bool second_pass) {
    pool.run([&](std::size_t w) {
      VoxelLookupStore lookup(*this, touched_by[w]);
      if (!second_pass) lookup.record_missing_blocks(&missing_by[w]);
      std::size_t updated = 0;
      const std::size_t first = items.size() * w / workers, last = items.size() * (w + 1) / workers;
      for (std::size_t j = first; j < last; ++j) {
        const std::size_t i = items[j];
        lookup.reset_missing();
        if (hits) updated += apply_hits(lattice_, lookup, ScanSegments<3, float>{origin, scan.ends + 3 * i, scan.is_hit + i, 1});
        else lookup.miss_ray(origin, scan.ends + 3 * i);  // counted when applied
        if (lookup.missing() && !second_pass) deferred_by[w].push_back(static_cast<std::uint32_t>(i));
      }
      updated_by[w] += updated;
    });
  };
  // Creates the blocks the first pass missed and repeats the updates that needed them.
  const auto finish = [&](bool hits) {
    std::vector<std::uint32_t> deferred;
    for (std::size_t w = 0; w < workers; ++w) {
      for (const std::uint64_t packed : missing_by[w]) find_or_create_block(packed);
      missing_by[w].clear();
      deferred.insert(deferred.end(), deferred_by[w].begin(), deferred_by[w].end());
      deferred_by[w].clear();
    }
    if (!deferred.empty()) run(deferred, hits, true);
  };
  run(hit_points, true, false);
  finish(true);
  // The voxels hit so far are the changed ones of the blocks each thread has listed.
  std::vector<std::vector<std::uint64_t>> hit_words_by(workers);
  for (std::size_t w = 0; w < workers; ++w) hit_words_by[w] = changed_words(touched_by[w]);
  run(order, false, false);
  finish(false);
  // Each block is in one thread's list: the threads update disjoint blocks.
  std::vector<std::size_t> applied_by(workers, 0);
  pool.run([&](std::size_t w) { applied_by[w] = apply_claimed_misses(touched_by[w], hit_words_by[w]); });
  std::size_t updated = 0;
  for (const std::size_t u : applied_by) updated += u;
  for (const std::size_t u : updated_by) updated += u;
  return updated;
}

InsertStats3D OccupancyGrid3D::insert_point_cloud(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>& points,
    const Eigen::Vector3d& origin, double max_range, int threads) {
  require_all_finite(origin, "origin");
  std::vector<float> xyz(static_cast<std::size_t>(points.rows()) * 3);
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int a = 0; a < 3; ++a) xyz[3 * i + a] = to_float(points(i, a));
  const float o[3] = {to_float(origin.x()), to_float(origin.y()), to_float(origin.z())};
  return insert_point_cloud(xyz.data(), static_cast<std::size_t>(points.rows()), o, max_range, threads);
}

float OccupancyGrid3D::log_odds_at_key(const CellKey<3>& key) const {
  if (!OctreeLattice::valid(key)) return std::numeric_limits<float>::quiet_NaN();
  const std::int64_t b = find_block(pack(key));
  if (b < 0) return std::numeric_limits<float>::quiet_NaN();
  return block_values(static_cast<std::size_t>(b))[voxel_index(key)];
}

void OccupancyGrid3D::set_log_odds(const CellKey<3>& key, float value) {
  require(OctreeLattice::valid(key), "key", "must lie in [0, 65536) on every axis");
  const std::int64_t found = find_block(pack(key));
  if (found < 0 && std::isnan(value)) return;
  const std::size_t b = found < 0 ? find_or_create_block(pack(key)) : static_cast<std::size_t>(found);
  float& l = block_values(b)[voxel_index(key)];
  const bool was_known = !std::isnan(l);
  if (std::isnan(value)) {
    l = value;
    if (was_known) --known_[b];
    return;
  }
  l = std::min(std::max(value, lo_), hi_);
  if (!was_known) ++known_[b];
}

std::optional<Eigen::Vector3d> OccupancyGrid3D::cast_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                                         double max_range) const {
  require_all_finite(origin, "origin");
  require_all_finite(direction, "direction");
  require(direction.norm() > 0.0, "direction", "must not be zero");
  require_positive(max_range, "max_range");
  // Past the key range nothing is occupied: a range beyond kRayCutSlack times the farthest
  // distance to it is cut there, so that the end stays finite (the walk itself is clipped to
  // the key range by walk_ray_in_box). Shorter rays are walked exactly as given.
  const double reach = origin.norm() + std::sqrt(3.0) * (OctreeLattice::kKeyOffset + 2) * lattice_.res;
  const double range = std::min(max_range, kRayCutSlack * reach);
  const Eigen::Vector3d end = origin + direction.normalized() * range;
  const double o[3] = {origin.x(), origin.y(), origin.z()}, e[3] = {end.x(), end.y(), end.z()};
  std::optional<Eigen::Vector3d> found;
  const auto occupied = [&](const CellKey<3>& k) { return log_odds_at_key(k) >= occ_; };
  walk_ray_in_box<3, double>(lattice_, OctreeLattice::key_box(), o, e, [&](const CellKey<3>& k) {
    if (!occupied(k)) return true;
    found = key_center(k);
    return false;
  });
  if (!found) {  // the walk leaves out the end's voxel (and is empty when it is the origin's)
    const CellKey<3> k = key_of(e[0], e[1], e[2]);
    if (occupied(k)) found = key_center(k);
  }
  return found;
}

std::size_t OccupancyGrid3D::num_known_voxels() const {
  std::size_t n = 0;
  for (const std::uint32_t k : known_) n += k;
  return n;
}

std::size_t OccupancyGrid3D::num_occupied_voxels() const {
  std::size_t n = 0;
  for_each_known([&](const CellKey<3>&, float l) { n += l >= occ_; });
  return n;
}

std::size_t OccupancyGrid3D::memory_bytes() const {
  return sizeof(*this) + chunks_.capacity() * sizeof(chunks_[0]) +
         chunks_.size() * static_cast<std::size_t>(kBlocksPerChunk) * kBlockVoxels * sizeof(float) +
         block_keys_.capacity() * sizeof(std::uint64_t) + known_.capacity() * sizeof(std::uint32_t) +
         changed_.capacity() * sizeof(std::uint64_t) + listed_.capacity() +
         table_keys_.capacity() * sizeof(std::uint64_t) + table_blocks_.capacity() * sizeof(std::uint32_t);
}

OccupancyGrid2D OccupancyGrid3D::project_2d(double z_min, double z_max) const {
  require(std::isfinite(z_min) && std::isfinite(z_max) && z_min <= z_max, "z_min", "must be finite and <= z_max");
  int x_lo = OctreeLattice::kKeyLimit, y_lo = OctreeLattice::kKeyLimit, x_hi = -1, y_hi = -1;
  const auto in_slab = [&](const CellKey<3>& k) {
    const double z = lattice_.key_to_coord(2, k[2]);
    return z >= z_min && z <= z_max;
  };
  for_each_known([&](const CellKey<3>& k, float) {
    if (!in_slab(k)) return;
    x_lo = std::min(x_lo, k[0]);
    x_hi = std::max(x_hi, k[0]);
    y_lo = std::min(y_lo, k[1]);
    y_hi = std::max(y_hi, k[1]);
  });
  const LogOddsClamp clamp{lo_, hi_, true};
  if (x_hi < 0) return OccupancyGrid2D(lattice_.res, 1, 1, {0.0, 0.0}, 0.5, clamp);
  const int w = x_hi - x_lo + 1, h = y_hi - y_lo + 1;
  // Up to 65536^2 cells: bounded before the grid and the `seen` marks are allocated.
  if (static_cast<std::int64_t>(w) * h > OccupancyGrid2D::kMaxCells)
    throw_invalid_argument("z_min", "..z_max covers known voxels over " + std::to_string(w) + " x " +
                                        std::to_string(h) + " cells, more than OccupancyGrid2D.max_cells = " +
                                        std::to_string(OccupancyGrid2D::kMaxCells));
  const Eigen::Vector2d corner((x_lo - OctreeLattice::kKeyOffset) * lattice_.res,
                               (y_lo - OctreeLattice::kKeyOffset) * lattice_.res);
  OccupancyGrid2D grid(lattice_.res, w, h, corner, 0.5, clamp);
  std::vector<std::uint8_t> seen(static_cast<std::size_t>(w) * h, 0);
  double* out = grid.data();
  for_each_known([&](const CellKey<3>& k, float l) {
    if (!in_slab(k)) return;
    const std::size_t i = static_cast<std::size_t>(k[1] - y_lo) * w + (k[0] - x_lo);
    out[i] = seen[i] ? std::max(out[i], static_cast<double>(l)) : l;
    seen[i] = 1;
  });
  return grid;
}

}  // namespace probslam
