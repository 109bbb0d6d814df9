#pragma once
// A std::vector whose resize leaves new elements of a trivial type uninitialised: for tables
// every element of which is written right after (a likelihood field, its pyramid), where a
// vector's zero fill was a tenth of GraphSLAM's time (memset over every field built).
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace probslam {

/// std::allocator, except that a value-initialisation (construct(p) with no argument) is a
/// default-initialisation: nothing is written for a trivial type.
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  using value_type = T;
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() noexcept = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}  // NOLINT: rebinding
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

template <typename T>
using UninitializedVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace probslam
