#include "probslam/core/state_file.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "regular_file.hpp"

namespace probslam {
namespace {

constexpr char kMagic[8] = {'P', 'S', 'L', 'S', 'T', 'A', 'T', 'E'};
// A class tag is a C++ class name: longer is corruption, not a tag.
constexpr std::uint32_t kMaxTagBytes = 64;

// FNV-1a, 64 bits: a flipped or lost byte anywhere in the payload changes it, so a damaged file
// is refused as such rather than loaded as a different, plausible state.
std::uint64_t fnv1a(const char* data, std::size_t size) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (std::size_t k = 0; k < size; ++k) {
    h ^= static_cast<unsigned char>(data[k]);
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

void StateReader::finish() const {
  if (remaining() != 0) fail(std::to_string(remaining()) + " bytes left over after the state (corrupt)");
}

void StateReader::fail(const std::string& what) const {
  throw StateError(source_ + ": " + what);
}

std::string frame_state(const std::string& tag, const std::string& payload) {
  StateWriter w;
  for (char c : kMagic) w.u8(static_cast<std::uint8_t>(c));
  w.u32(kStateFormatVersion);
  w.string(tag);
  w.u64(payload.size());
  w.u64(fnv1a(payload.data(), payload.size()));
  return w.payload() + payload;
}

PayloadView unframe_state(const std::string& framed, const std::string& tag, const std::string& source) {
  StateReader r(framed.data(), framed.size(), source);
  const auto fail = [&](const std::string& what) { r.fail(what); };
  if (framed.size() < sizeof kMagic || std::memcmp(framed.data(), kMagic, sizeof kMagic) != 0)
    fail("not a probslam state file (no PSLSTATE magic)");
  for (std::size_t k = 0; k < sizeof kMagic; ++k) r.u8();
  const std::uint32_t version = r.u32();
  if (version != kStateFormatVersion)
    fail("state format version " + std::to_string(version) + " is not supported (this build reads version " +
         std::to_string(kStateFormatVersion) + ")");
  const std::uint64_t tag_size = r.u64();
  if (tag_size > kMaxTagBytes || tag_size > r.remaining()) fail("truncated or corrupt class tag");
  std::string found(framed.data() + (framed.size() - r.remaining()), static_cast<std::size_t>(tag_size));
  for (std::uint64_t k = 0; k < tag_size; ++k) r.u8();
  if (found != tag) fail("holds a " + found + ", not a " + tag);
  const std::uint64_t size = r.u64();
  const std::uint64_t checksum = r.u64();
  if (size != r.remaining())
    fail("truncated or padded: the header announces " + std::to_string(size) + " bytes of state, the file holds " +
         std::to_string(r.remaining()));
  const char* data = framed.data() + (framed.size() - r.remaining());
  if (fnv1a(data, static_cast<std::size_t>(size)) != checksum) fail("corrupt (the checksum does not match)");
  return {data, static_cast<std::size_t>(size)};
}

void write_state_file(const std::string& path, const std::string& bytes) {
  if (path.empty()) throw std::invalid_argument("path: empty");
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::invalid_argument("path: cannot write '" + path + "'");
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error("failed writing '" + path + "'");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw std::invalid_argument("path: cannot write '" + path + "' (" + ec.message() + ")");
  }
}

std::string read_state_file(const std::string& path) {
  std::ifstream in = core_detail::open_regular_file(path, "path");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw std::invalid_argument("path: cannot read '" + path + "'");
  return buffer.str();
}

}  // namespace probslam
