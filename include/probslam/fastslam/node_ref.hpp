#pragma once
// Immutable, reference-counted nodes shared between particles (the persistent landmark trees and
// pose paths of the particle filters), and the 64-bit mix their hashes and seeds use.
#include <atomic>
#include <cstdint>
#include <utility>

namespace probslam {

/// splitmix64's finaliser: a bijective 64-bit mix.
inline std::uint64_t mix64(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// A counted reference to an immutable node T. T has `mutable std::atomic<std::uint32_t> refs`
/// (1 when built) and `static void destroy(const T*)`, called when the last reference goes.
template <class T>
class NodeRef {
 public:
  NodeRef() noexcept = default;
  /// Takes over the reference a freshly built node holds.
  static NodeRef adopt(const T* p) noexcept {
    NodeRef r;
    r.p_ = p;
    return r;
  }
  NodeRef(const NodeRef& o) noexcept : p_(o.p_) {
    if (p_) p_->refs.fetch_add(1, std::memory_order_relaxed);
  }
  NodeRef(NodeRef&& o) noexcept : p_(o.p_) { o.p_ = nullptr; }
  NodeRef& operator=(NodeRef o) noexcept {
    std::swap(p_, o.p_);
    return *this;
  }
  ~NodeRef() { reset(); }
  void reset() noexcept {
    if (p_ && p_->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) T::destroy(p_);
    p_ = nullptr;
  }
  /// Gives up the reference without releasing it (for iterative destruction of long chains).
  const T* detach() noexcept {
    const T* p = p_;
    p_ = nullptr;
    return p;
  }
  const T* get() const noexcept { return p_; }
  const T* operator->() const noexcept { return p_; }
  const T& operator*() const noexcept { return *p_; }
  explicit operator bool() const noexcept { return p_ != nullptr; }

 private:
  const T* p_ = nullptr;
};

}  // namespace probslam
