#include "probslam/io/ros_map.hpp"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "probslam/core/check.hpp"
#include "text_fields.hpp"

namespace probslam {
namespace {

constexpr unsigned char kOccupiedPixel = 0;
constexpr unsigned char kFreePixel = 254;
constexpr unsigned char kUnknownPixel = 205;
// The certainty a loaded map gives its known cells: OctoMap's default clamping bounds.
constexpr double kLoadedOccupied = 0.971;
constexpr double kLoadedFree = 0.1192;
// map_server YAML files are a few hundred bytes; a larger one is not a map description, and
// reading it line by line into a map of keys would cost memory for nothing.
constexpr std::uintmax_t kMaxYamlBytes = 1 << 20;
// Pixels of a map image: 2^27 (a 11.6 km square at 1 m, or 580 m at 5 cm) becomes 1 GiB of
// log-odds; larger images are refused before anything is allocated.
constexpr std::size_t kMaxMapPixels = std::size_t{1} << 27;

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw std::invalid_argument(where + ": " + what);
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::string unquote(const std::string& s) {
  if (s.size() >= 2 && (s.front() == '"' || s.front() == '\'') && s.back() == s.front())
    return s.substr(1, s.size() - 2);
  return s;
}

std::string directory_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? "" : path.substr(0, slash + 1);
}

std::string stem_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const auto dot = name.find_last_of('.');
  return dot == std::string::npos ? name : name.substr(0, dot);
}

double parse_number(const std::string& text, const std::string& where, const std::string& key) {
  // strtod, not stod: stod throws on underflow, so a subnormal value this writer itself wrote
  // (e.g. free_thresh 4.9e-324) could not be read back. Overflow still fails (isfinite below).
  const char* begin = text.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin) fail(where, key + " is not a number: '" + text + "'");
  const auto used = static_cast<std::size_t>(end - begin);
  if (trim(text.substr(used)) != "" || !std::isfinite(v)) fail(where, key + " is not a finite number: '" + text + "'");
  return v;
}

// The flat subset of YAML that map_server files use: `key: value` and `origin: [x, y, yaw]`.
struct YamlEntry {
  std::string value;
  long line;
};

std::map<std::string, YamlEntry> read_flat_yaml(const std::string& path) {
  io_detail::require_regular_file(path, "yaml_path");
  if (std::filesystem::file_size(path) > kMaxYamlBytes)
    fail(path, "larger than " + std::to_string(kMaxYamlBytes) + " bytes (kMaxYamlBytes): not a map_server YAML file");
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("yaml_path: cannot open '" + path + "'");
  std::map<std::string, YamlEntry> entries;
  std::string line;
  long n = 0;
  while (std::getline(in, line)) {
    ++n;
    const auto hash = line.find('#');
    const std::string body = trim(hash == std::string::npos ? line : line.substr(0, hash));
    if (body.empty() || body == "---") continue;
    const auto colon = body.find(':');
    if (colon == std::string::npos) fail(path + ":" + std::to_string(n), "expected 'key: value'");
    entries[trim(body.substr(0, colon))] = {trim(body.substr(colon + 1)), n};
  }
  return entries;
}

struct Pgm {
  int width = 0, height = 0, maxval = 255;
  std::vector<unsigned char> pixels;  // row 0 = top
};

Pgm read_pgm(const std::string& path) {
  io_detail::require_regular_file(path, "image", io_detail::NamedBy::kFile);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot open the map image");
  std::string magic(2, '\0');
  in.read(magic.data(), 2);
  if (magic != "P5" && magic != "P2") fail(path, "not a PGM file (magic '" + magic + "')");
  Pgm pgm;
  int* header[3] = {&pgm.width, &pgm.height, &pgm.maxval};
  for (int* field : header) {
    in >> std::ws;
    while (in.peek() == '#') {
      std::string comment;
      std::getline(in, comment);
      in >> std::ws;
    }
    if (!(in >> *field) || *field <= 0) fail(path, "malformed PGM header");
  }
  if (pgm.maxval > 255) fail(path, "16-bit PGM files are not supported");
  const std::size_t n = static_cast<std::size_t>(pgm.width) * pgm.height;
  if (n > kMaxMapPixels)
    fail(path, std::to_string(pgm.width) + " x " + std::to_string(pgm.height) + " pixels exceed the limit of " +
                   std::to_string(kMaxMapPixels) + " (kMaxMapPixels)");
  // Refuse sizes the file cannot hold before allocating (a P2 pixel takes >= 2 bytes).
  const std::streamoff here = in.tellg();
  in.seekg(0, std::ios::end);
  const double remaining = static_cast<double>(in.tellg() - here);
  in.seekg(here);
  if (remaining < static_cast<double>(n) * (magic == "P5" ? 1.0 : 2.0) - 1.0) fail(path, "truncated PGM data");
  pgm.pixels.resize(n);
  if (magic == "P5") {
    in.get();  // the single whitespace after maxval
    if (!in.read(reinterpret_cast<char*>(pgm.pixels.data()), static_cast<std::streamsize>(n)))
      fail(path, "truncated PGM data");
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      int v = -1;
      if (!(in >> v) || v < 0 || v > pgm.maxval) fail(path, "truncated PGM data");
      pgm.pixels[i] = static_cast<unsigned char>(v);
    }
  }
  return pgm;
}

}  // namespace

void save_ros_map(const OccupancyGrid2D& grid, const std::string& yaml_path, const RosMapOptions& options) {
  require_probability(options.occupied_thresh, "occupied_thresh");
  require_probability(options.free_thresh, "free_thresh");
  require(options.free_thresh < options.occupied_thresh, "free_thresh", "must be below occupied_thresh");
  // Refused before the image is written, so that a bad path leaves no half-written map.
  if (yaml_path.empty() || yaml_path.back() == '/' || std::filesystem::is_directory(yaml_path))
    throw std::invalid_argument("yaml_path: must name a file, got '" + yaml_path + "'");
  const std::string image = stem_of(yaml_path) + ".pgm";
  const std::string pgm_path = directory_of(yaml_path) + image;
  const RowMatrixXd p = grid.probability();
  std::ofstream pgm(pgm_path, std::ios::binary);
  if (!pgm) throw std::invalid_argument("yaml_path: cannot write '" + pgm_path + "'");
  pgm << "P5\n# CREATOR: probslam " << grid.resolution() << " m/pix\n"
      << grid.width() << " " << grid.height() << "\n255\n";
  std::vector<unsigned char> row(grid.width());
  for (int i = grid.height() - 1; i >= 0; --i) {
    for (int j = 0; j < grid.width(); ++j) {
      const double v = p(i, j);
      row[j] = v > options.occupied_thresh ? kOccupiedPixel : (v < options.free_thresh ? kFreePixel : kUnknownPixel);
    }
    pgm.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size()));
  }
  if (!pgm) throw std::runtime_error("failed writing '" + pgm_path + "'");

  std::ofstream yaml(yaml_path);
  if (!yaml) throw std::invalid_argument("yaml_path: cannot write '" + yaml_path + "'");
  yaml.precision(17);
  yaml << "image: " << image << "\nmode: trinary\nresolution: " << grid.resolution() << "\norigin: ["
       << grid.origin().x() << ", " << grid.origin().y() << ", 0.0]\nnegate: 0\noccupied_thresh: "
       << options.occupied_thresh << "\nfree_thresh: " << options.free_thresh << "\n";
  if (!yaml) throw std::runtime_error("failed writing '" + yaml_path + "'");
}

OccupancyGrid2D load_ros_map(const std::string& yaml_path) {
  const auto entries = read_flat_yaml(yaml_path);
  const auto get = [&](const std::string& key) -> const YamlEntry& {
    const auto it = entries.find(key);
    if (it == entries.end()) fail(yaml_path, "missing key '" + key + "'");
    return it->second;
  };
  const auto where = [&](const YamlEntry& e) { return yaml_path + ":" + std::to_string(e.line); };
  const auto number = [&](const std::string& key) {
    const YamlEntry& e = get(key);
    return parse_number(e.value, where(e), key);
  };

  const double resolution = number("resolution");
  if (!(resolution > 0)) fail(where(get("resolution")), "resolution must be > 0");
  const double occupied_thresh = number("occupied_thresh");
  const double free_thresh = number("free_thresh");
  const bool negate = entries.count("negate") ? number("negate") != 0.0 : false;
  std::string mode = entries.count("mode") ? unquote(get("mode").value) : "trinary";
  if (mode != "trinary" && mode != "scale") fail(where(get("mode")), "unsupported mode '" + mode + "'");

  const YamlEntry& origin_entry = get("origin");
  std::string list = origin_entry.value;
  if (list.size() < 2 || list.front() != '[' || list.back() != ']')
    fail(where(origin_entry), "origin must be a list [x, y, yaw]");
  std::stringstream items(list.substr(1, list.size() - 2));
  std::vector<double> origin;
  for (std::string item; std::getline(items, item, ',');) origin.push_back(parse_number(trim(item), where(origin_entry), "origin"));
  if (origin.size() != 3) fail(where(origin_entry), "origin must have exactly three numbers");
  if (origin[2] != 0.0) fail(where(origin_entry), "rotated maps (yaw != 0) are not supported");

  const std::string image = unquote(get("image").value);
  const Pgm pgm = read_pgm(image.rfind('/', 0) == 0 ? image : directory_of(yaml_path) + image);
  OccupancyGrid2D grid(resolution, pgm.width, pgm.height, {origin[0], origin[1]});
  const LogOddsClamp bounds = LogOddsClamp::from_probabilities(kLoadedFree, kLoadedOccupied);
  auto cells = grid.log_odds();
  for (int r = 0; r < pgm.height; ++r) {
    for (int c = 0; c < pgm.width; ++c) {
      const double v = static_cast<double>(pgm.pixels[static_cast<std::size_t>(r) * pgm.width + c]) / pgm.maxval;
      const double p = negate ? v : 1.0 - v;
      double l = grid.prior_log_odds();
      if (p > occupied_thresh) l = mode == "trinary" ? bounds.max : bounds.apply(logit(std::min(p, kLoadedOccupied)));
      else if (p < free_thresh) l = mode == "trinary" ? bounds.min : bounds.apply(logit(std::max(p, kLoadedFree)));
      cells(pgm.height - 1 - r, c) = l;
    }
  }
  return grid;
}

}  // namespace probslam
