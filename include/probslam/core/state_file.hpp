#pragma once
// The serialisation kernel behind every class's save / load and pickle (docs/file_format.md):
// a little-endian byte stream of primitives, vectors and Eigen matrices, framed by a header
// (magic, format version, class tag, payload length, checksum). Doubles travel as their IEEE
// bits, so a loaded object is bit for bit the saved one.
//
// Reading is bounded: every length read from the stream is checked against the bytes left
// before anything is allocated, so a corrupt length cannot ask for gigabytes, and every error is
// std::invalid_argument "<source>: <what is wrong>", source being the path (or "state" for bytes).
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace probslam {

/// Version of the layout every class writes; a reader refuses any other.
/// 2: SubmapSlam2D holds the saved map a run started from (issue 36's `slam --map`).
/// 3: the scan matcher holds constant_velocity, match_fraction and whether it started on a
/// saved map (issue 51); FastSlam its provisional landmarks (min_sightings, issue 50).
/// 4: EkfSlam keeps its landmarks' signatures apart from the dense state (issue 50's speed);
/// MonteCarloLocalization's options hold resample_interval (issue 52: an option added by its
/// describe() line alone).
/// 5: the options of the laser SLAM classes and of FastSlam written through their describe()
/// (issue 52): the scan matcher's no longer hold the match's prior, which every owner sets per
/// match; FastSlam's noise and start pose follow its options (the model is the constructor's).
/// 6: the scan matcher's options hold `search` (issue 54, the frontend's local optimiser).
/// 7: GridFastSlam's proposal options hold `search` (issue 54, the proposal's Gauss-Newton).
inline constexpr std::uint32_t kStateFormatVersion = 7;

/// What a reader throws: "<source>: <what is wrong>".
class StateError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Appends primitives to a byte string, little-endian.
class StateWriter {
 public:
  void u8(std::uint8_t v) { out_.push_back(static_cast<char>(v)); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void u32(std::uint32_t v) { put_le(v, 4); }
  void i32(std::int32_t v) { put_le(static_cast<std::uint32_t>(v), 4); }
  void u64(std::uint64_t v) { put_le(v, 8); }
  void i64(std::int64_t v) { put_le(static_cast<std::uint64_t>(v), 8); }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    put_le(bits, 8);
  }
  void f32(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    put_le(bits, 4);
  }
  void count(std::size_t n) { u64(static_cast<std::uint64_t>(n)); }
  void string(const std::string& s) {
    count(s.size());
    out_.append(s);
  }
  void doubles(const std::vector<double>& v) {
    count(v.size());
    for (double x : v) f64(x);
  }
  template <typename Allocator>
  void floats(const std::vector<float, Allocator>& v) {
    count(v.size());
    for (float x : v) f32(x);
  }
  void longs(const std::vector<long>& v) {
    count(v.size());
    for (long x : v) i64(x);
  }
  void ints(const std::vector<int>& v) {
    count(v.size());
    for (int x : v) i32(x);
  }
  void bytes(const std::vector<std::uint8_t>& v) {
    count(v.size());
    for (std::uint8_t x : v) u8(x);
  }
  /// rows, cols, then the entries column by column (whatever the matrix's storage order).
  template <typename Derived>
  void matrix(const Eigen::DenseBase<Derived>& m) {
    i64(m.rows());
    i64(m.cols());
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      for (Eigen::Index r = 0; r < m.rows(); ++r) f64(m(r, c));
  }

  const std::string& payload() const { return out_; }

 private:
  void put_le(std::uint64_t v, int n) {
    for (int k = 0; k < n; ++k) out_.push_back(static_cast<char>((v >> (8 * k)) & 0xff));
  }
  std::string out_;
};

/// Reads what StateWriter wrote from a byte string it does not own (the string must outlive it).
class StateReader {
 public:
  StateReader(const char* data, std::size_t size, std::string source)
      : data_(data), size_(size), source_(std::move(source)) {}

  std::uint8_t u8() { return static_cast<std::uint8_t>(get_le(1)); }
  bool boolean() {
    const std::uint8_t v = u8();
    if (v > 1) fail("a flag holds " + std::to_string(v) + " (0 or 1 expected)");
    return v == 1;
  }
  std::uint32_t u32() { return static_cast<std::uint32_t>(get_le(4)); }
  std::int32_t i32() { return static_cast<std::int32_t>(static_cast<std::uint32_t>(get_le(4))); }
  std::uint64_t u64() { return get_le(8); }
  std::int64_t i64() { return static_cast<std::int64_t>(get_le(8)); }
  double f64() {
    const std::uint64_t bits = get_le(8);
    double v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  float f32() {
    const std::uint32_t bits = static_cast<std::uint32_t>(get_le(4));
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  /// A count of items of at least `item_bytes` bytes each, checked against the bytes left.
  std::size_t count(std::size_t item_bytes) {
    const std::uint64_t n = u64();
    if (item_bytes > 0 && n > remaining() / item_bytes)
      fail("a length of " + std::to_string(n) + " items exceeds the " + std::to_string(remaining()) +
           " bytes left (truncated or corrupt)");
    return static_cast<std::size_t>(n);
  }
  /// An int within [lo, hi]; `what` names the field in the error.
  int int_in(int lo, int hi, const char* what) {
    const std::int32_t v = i32();
    if (v < lo || v > hi)
      fail(std::string(what) + " is " + std::to_string(v) + ", outside [" + std::to_string(lo) + ", " +
           std::to_string(hi) + "]");
    return v;
  }
  std::string string() {
    const std::size_t n = count(1);
    std::string s(data_ + pos_, n);
    pos_ += n;
    return s;
  }
  std::vector<double> doubles() { return items<double>(8, [this] { return f64(); }); }
  std::vector<float> floats() { return items<float>(4, [this] { return f32(); }); }
  std::vector<long> longs() { return items<long>(8, [this] { return static_cast<long>(i64()); }); }
  std::vector<int> ints() { return items<int>(4, [this] { return static_cast<int>(i32()); }); }
  std::vector<std::uint8_t> bytes() { return items<std::uint8_t>(1, [this] { return u8(); }); }

  /// A matrix of MatrixType; fixed dimensions must match. The dynamic ones are counts, checked
  /// against the bytes left before allocation or any loop: each alone as a count of 8-byte
  /// entries (so an empty 0 x 2^62 matrix is refused, not walked column by column), and their
  /// product without overflow.
  template <typename MatrixType>
  MatrixType matrix() {
    const std::int64_t rows = i64(), cols = i64();
    if (rows < 0 || cols < 0) fail("a matrix has negative dimensions");
    constexpr bool kDynamicRows = MatrixType::RowsAtCompileTime == Eigen::Dynamic;
    constexpr bool kDynamicCols = MatrixType::ColsAtCompileTime == Eigen::Dynamic;
    if ((!kDynamicRows && rows != MatrixType::RowsAtCompileTime) || (!kDynamicCols && cols != MatrixType::ColsAtCompileTime))
      fail("a matrix is " + std::to_string(rows) + " x " + std::to_string(cols) + ", not of the expected size");
    const std::uint64_t entries_left = remaining() / 8;
    const auto r64 = static_cast<std::uint64_t>(rows), c64 = static_cast<std::uint64_t>(cols);
    if ((kDynamicRows && r64 > entries_left) || (kDynamicCols && c64 > entries_left) ||
        (c64 > 0 && r64 > entries_left / c64))
      fail("a " + std::to_string(rows) + " x " + std::to_string(cols) + " matrix exceeds the " +
           std::to_string(remaining()) + " bytes left (truncated or corrupt)");
    MatrixType m(rows, cols);
    for (Eigen::Index c = 0; c < cols; ++c)
      for (Eigen::Index r = 0; r < rows; ++r) m(r, c) = f64();
    return m;
  }

  std::size_t remaining() const { return size_ - pos_; }
  /// Throws unless at least `bytes` are left: checked before allocating what they will fill.
  void require_bytes(double bytes, const char* what) const {
    if (!(bytes <= static_cast<double>(remaining())))
      fail(std::string(what) + " needs " + std::to_string(bytes) + " bytes, " + std::to_string(remaining()) +
           " are left (truncated or corrupt)");
  }
  const std::string& source() const { return source_; }
  /// Throws unless every byte was read.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::uint64_t get_le(int n) {
    if (remaining() < static_cast<std::size_t>(n)) fail("truncated (the state ends early)");
    std::uint64_t v = 0;
    for (int k = 0; k < n; ++k) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(data_[pos_ + k])) << (8 * k);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  template <typename T, typename F>
  std::vector<T> items(std::size_t item_bytes, F&& read) {
    const std::size_t n = count(item_bytes);
    std::vector<T> v;
    v.reserve(n);
    for (std::size_t k = 0; k < n; ++k) v.push_back(read());
    return v;
  }

  const char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string source_;
};

/// f(), a std::invalid_argument from it (a constructor or setter refusing a value read from the
/// state) reported as the state's error, naming `what`.
template <typename F>
auto validated(const StateReader& r, const char* what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const StateError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    r.fail(std::string("invalid ") + what + ": " + e.what());
  }
}

/// The whole state of one object: header (magic "PSLSTATE", kStateFormatVersion, class tag,
/// payload length, FNV-1a 64 checksum of the payload) and payload.
std::string frame_state(const std::string& tag, const std::string& payload);
/// Checks a framed state's header against `tag` and returns where its payload lies in `framed`.
/// source names the file (or "state") in the errors.
struct PayloadView {
  const char* data;
  std::size_t size;
};
PayloadView unframe_state(const std::string& framed, const std::string& tag, const std::string& source);

/// Writes bytes to path (through a temporary file renamed over it, so that a failed or
/// interrupted save never leaves a half-written file under that name).
void write_state_file(const std::string& path, const std::string& bytes);
/// The whole file; std::invalid_argument naming `path` if it is not a readable regular file.
std::string read_state_file(const std::string& path);

/// The bytes of obj's state: T provides kStateTag, write_state(StateWriter&) const.
template <typename T>
std::string state_bytes(const T& obj) {
  StateWriter w;
  obj.write_state(w);
  return frame_state(T::kStateTag, w.payload());
}
/// The object the bytes hold: T provides static T read_state(StateReader&). The bytes must be
/// consumed exactly; anything else is refused before an object is returned.
template <typename T>
T object_from_state(const std::string& bytes, const std::string& source) {
  const PayloadView p = unframe_state(bytes, T::kStateTag, source);
  StateReader r(p.data, p.size, source);
  T obj = T::read_state(r);
  r.finish();
  return obj;
}
template <typename T>
void save_state(const T& obj, const std::string& path) {
  write_state_file(path, state_bytes(obj));
}
template <typename T>
T load_state(const std::string& path) {
  return object_from_state<T>(read_state_file(path), path);
}

}  // namespace probslam
