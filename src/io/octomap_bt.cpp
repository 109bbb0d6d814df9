#include "probslam/io/octomap_bt.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "text_fields.hpp"

namespace probslam {
namespace {

constexpr const char* kFileHeader = "# Octomap OcTree binary file";
constexpr int kTreeDepth = 16;  // OctoMap's OcTree: 16 levels, keys of 16 bits

// Two-bit child codes of the format.
constexpr unsigned kUnknown = 0;  // 00
constexpr unsigned kFree = 1;     // bit 2i set: "10" in OctoMap's bitset notation
constexpr unsigned kOccupied = 2; // bit 2i+1 set: "01"
constexpr unsigned kInner = 3;    // 11

std::uint64_t morton(const CellKey<3>& k) {
  std::uint64_t m = 0;
  for (int b = 0; b < kTreeDepth; ++b)
    for (int a = 0; a < 3; ++a) m |= static_cast<std::uint64_t>((k[a] >> b) & 1) << (3 * b + a);
  return m;
}

struct Leaf {
  std::uint64_t code;
  bool occupied;
};

class Encoder {
 public:
  explicit Encoder(const std::vector<Leaf>& leaves) : leaves_(leaves), occupied_before_(leaves.size() + 1, 0) {
    for (std::size_t i = 0; i < leaves.size(); ++i) occupied_before_[i + 1] = occupied_before_[i] + leaves[i].occupied;
  }

  /// Encodes the node at `depth` holding leaves [lo, hi) (all sharing the node's prefix).
  void encode(std::size_t lo, std::size_t hi, int depth) {
    const int shift = 3 * (kTreeDepth - 1 - depth);
    std::size_t bounds[9];
    bounds[0] = lo;
    std::size_t i = lo;
    for (unsigned c = 0; c < 8; ++c) {
      while (i < hi && ((leaves_[i].code >> shift) & 7) == c) ++i;
      bounds[c + 1] = i;
    }
    const std::uint64_t child_volume = std::uint64_t{1} << shift;  // voxels under one child
    unsigned codes[8];
    std::uint8_t bytes[2] = {0, 0};
    for (unsigned c = 0; c < 8; ++c) {
      const std::size_t n = bounds[c + 1] - bounds[c];
      const std::size_t occ = occupied_before_[bounds[c + 1]] - occupied_before_[bounds[c]];
      if (n == 0) codes[c] = kUnknown;
      else if (n == child_volume && (occ == 0 || occ == n)) codes[c] = occ ? kOccupied : kFree;  // pruned
      else codes[c] = kInner;
      if (codes[c] != kUnknown) ++nodes;
      bytes[c / 4] |= static_cast<std::uint8_t>(codes[c] << (2 * (c % 4)));
    }
    data.push_back(static_cast<char>(bytes[0]));
    data.push_back(static_cast<char>(bytes[1]));
    for (unsigned c = 0; c < 8; ++c)
      if (codes[c] == kInner) encode(bounds[c], bounds[c + 1], depth + 1);
  }

  std::string data;
  std::size_t nodes = 0;

 private:
  const std::vector<Leaf>& leaves_;
  std::vector<std::size_t> occupied_before_;
};

struct ParsedLeaf {
  CellKey<3> base;
  int level;  // the leaf covers 2^level voxels per axis
  bool occupied;
};

class Decoder {
 public:
  Decoder(std::istream& in, const std::string& path) : in_(in), path_(path) {}

  void decode(const CellKey<3>& base, int depth) {
    char raw[2];
    if (!in_.read(raw, 2)) fail("truncated tree data");
    const int level = kTreeDepth - 1 - depth;  // children cover 2^level voxels per axis
    unsigned codes[8];
    for (unsigned c = 0; c < 8; ++c)
      codes[c] = (static_cast<unsigned char>(raw[c / 4]) >> (2 * (c % 4))) & 3u;
    for (unsigned c = 0; c < 8; ++c) {
      if (codes[c] == kUnknown) continue;
      ++nodes;
      const CellKey<3> child{base[0] + static_cast<int>((c & 1) << level), base[1] + static_cast<int>(((c >> 1) & 1) << level),
                             base[2] + static_cast<int>(((c >> 2) & 1) << level)};
      if (codes[c] == kInner) continue;
      voxels += std::size_t{1} << (3 * level);
      if (voxels > kMaxBtImportVoxels) fail("expands to more than " + std::to_string(kMaxBtImportVoxels) + " voxels (kMaxBtImportVoxels)");
      leaves.push_back({child, level, codes[c] == kOccupied});
    }
    for (unsigned c = 0; c < 8; ++c) {
      if (codes[c] != kInner) continue;
      if (level == 0) fail("malformed tree: a voxel at full depth has children");
      decode({base[0] + static_cast<int>((c & 1) << level), base[1] + static_cast<int>(((c >> 1) & 1) << level),
              base[2] + static_cast<int>(((c >> 2) & 1) << level)},
             depth + 1);
    }
  }

  [[noreturn]] void fail(const std::string& what) const { throw std::invalid_argument(path_ + ": " + what); }

  std::vector<ParsedLeaf> leaves;
  std::size_t nodes = 1;  // the root
  std::size_t voxels = 0;

 private:
  std::istream& in_;
  const std::string& path_;
};

}  // namespace

std::size_t write_octomap_bt(const OccupancyGrid3D& grid, const std::string& path) {
  std::vector<Leaf> leaves;
  leaves.reserve(grid.num_known_voxels());
  const float occ = grid.occupancy_log_odds();
  grid.for_each_known([&](const CellKey<3>& k, float l) { leaves.push_back({morton(k), l >= occ}); });
  std::sort(leaves.begin(), leaves.end(), [](const Leaf& a, const Leaf& b) { return a.code < b.code; });
  Encoder encoder(leaves);
  std::size_t size = 0;
  if (!leaves.empty()) {
    encoder.encode(0, leaves.size(), 0);
    size = encoder.nodes + 1;  // children counted, plus the root
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
  out << kFileHeader << "\n# written by probslam (maximum-likelihood occupancy)\n#\n";
  out << "id OcTree\nsize " << size << "\nres " << std::setprecision(std::numeric_limits<double>::max_digits10)
      << grid.resolution() << "\ndata\n";
  out.write(encoder.data.data(), static_cast<std::streamsize>(encoder.data.size()));
  out.flush();
  if (!out) throw std::runtime_error("failed writing '" + path + "'");
  return size;
}

OccupancyGrid3D read_octomap_bt(const std::string& path, const OccupancyParams3D& params) {
  std::ifstream in = io_detail::open_regular_file(path, "path");
  const auto fail = [&](const std::string& what) -> void { throw std::invalid_argument(path + ": " + what); };
  std::string line;
  if (!std::getline(in, line) || line.compare(0, std::char_traits<char>::length(kFileHeader), kFileHeader) != 0)
    fail("not an OctoMap binary tree (.bt) file");
  std::string id;
  double res = 0.0;
  long long size = -1;
  bool data = false;
  while (!data && std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string token;
    fields >> token;
    if (token == "id") fields >> id;
    else if (token == "size") fields >> size;
    else if (token == "res") fields >> res;
    else if (token == "data") data = true;
    else continue;  // OctoMap skips unknown header keywords too
    if (!fields && !data) fail("unreadable header line '" + line + "'");
  }
  if (!data) fail("header without 'data' line");
  if (id != "OcTree") fail("tree type '" + id + "' is not OcTree");
  if (size < 0) fail("header without a valid 'size'");
  if (!(std::isfinite(res) && res > 0.0)) fail("header without a valid 'res'");

  OccupancyGrid3D grid(res, params);
  if (size == 0) return grid;
  Decoder decoder(in, path);
  decoder.decode({0, 0, 0}, 0);
  if (decoder.nodes != static_cast<std::size_t>(size))
    fail("tree holds " + std::to_string(decoder.nodes) + " nodes, the header says " + std::to_string(size));
  const float occupied = grid.clamp_max_log_odds(), free = grid.clamp_min_log_odds();
  for (const ParsedLeaf& leaf : decoder.leaves) {
    const int side = 1 << leaf.level;
    for (int z = 0; z < side; ++z)
      for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x)
          grid.set_log_odds({leaf.base[0] + x, leaf.base[1] + y, leaf.base[2] + z}, leaf.occupied ? occupied : free);
  }
  return grid;
}

}  // namespace probslam
