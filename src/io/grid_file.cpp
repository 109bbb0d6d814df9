#include "probslam/io/grid_file.hpp"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "text_fields.hpp"

namespace probslam {
namespace {

constexpr char kMagic[8] = {'P', 'S', 'G', 'R', 'I', 'D', '2', 'D'};
constexpr std::uint32_t kVersion = 1;

struct Header {  // written field by field, little-endian (checked at run time)
  std::uint32_t version;
  std::int32_t width, height;
  double resolution, x0, y0, p_prior, p_hit, p_miss;
  std::uint8_t clamp_enabled;
  double clamp_min, clamp_max;
};

bool little_endian() {
  const std::uint16_t probe = 1;
  unsigned char first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

template <typename T>
void put(std::ofstream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
void get(std::ifstream& in, T& v, const std::string& path) {
  if (!in.read(reinterpret_cast<char*>(&v), sizeof(T))) throw std::invalid_argument(path + ": truncated grid file");
}

}  // namespace

void save_grid(const OccupancyGrid2D& grid, const std::string& path) {
  if (!little_endian()) throw std::runtime_error("save_grid supports little-endian machines only");
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
  out.write(kMagic, sizeof(kMagic));
  put(out, kVersion);
  put(out, static_cast<std::int32_t>(grid.width()));
  put(out, static_cast<std::int32_t>(grid.height()));
  for (double v : {grid.resolution(), grid.origin().x(), grid.origin().y(), grid.p_prior(),
                   grid.beam_model().p_hit, grid.beam_model().p_miss})
    put(out, v);
  put(out, static_cast<std::uint8_t>(grid.clamp().enabled));
  put(out, grid.clamp().min);
  put(out, grid.clamp().max);
  out.write(reinterpret_cast<const char*>(grid.data()),
            static_cast<std::streamsize>(sizeof(double) * grid.width() * grid.height()));
  if (!out) throw std::runtime_error("failed writing '" + path + "'");
}

OccupancyGrid2D load_grid(const std::string& path) {
  if (!little_endian()) throw std::runtime_error("load_grid supports little-endian machines only");
  io_detail::require_regular_file(path, "path");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("path: cannot open '" + path + "'");
  char magic[sizeof(kMagic)];
  if (!in.read(magic, sizeof(magic)) || std::memcmp(magic, kMagic, sizeof(kMagic)) != 0)
    throw std::invalid_argument(path + ": not a probslam grid file");
  Header h{};
  get(in, h.version, path);
  if (h.version != kVersion) throw std::invalid_argument(path + ": unsupported grid file version " + std::to_string(h.version));
  get(in, h.width, path);
  get(in, h.height, path);
  for (double* v : {&h.resolution, &h.x0, &h.y0, &h.p_prior, &h.p_hit, &h.p_miss}) get(in, *v, path);
  get(in, h.clamp_enabled, path);
  get(in, h.clamp_min, path);
  get(in, h.clamp_max, path);
  // Check the payload's size before allocating, so a corrupt header cannot ask for gigabytes.
  const std::streamoff header_end = in.tellg();
  in.seekg(0, std::ios::end);
  const std::streamoff payload = in.tellg() - header_end;
  in.seekg(header_end);
  if (h.width <= 0 || h.height <= 0 ||
      static_cast<double>(payload) != 8.0 * static_cast<double>(h.width) * static_cast<double>(h.height))
    throw std::invalid_argument(path + ": grid size in the header does not match the file's length");
  // The constructor validates every field and names the bad one.
  OccupancyGrid2D grid(h.resolution, h.width, h.height, {h.x0, h.y0}, h.p_prior,
                       h.clamp_enabled ? LogOddsClamp{h.clamp_min, h.clamp_max, true} : LogOddsClamp::none());
  grid.set_beam_model({h.p_hit, h.p_miss});
  if (!in.read(reinterpret_cast<char*>(grid.data()),
               static_cast<std::streamsize>(sizeof(double) * grid.width() * grid.height())))
    throw std::invalid_argument(path + ": truncated grid file");
  if (in.peek() != std::ifstream::traits_type::eof()) throw std::invalid_argument(path + ": trailing data in grid file");
  return grid;
}

}  // namespace probslam
