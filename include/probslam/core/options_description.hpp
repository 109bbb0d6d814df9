#pragma once
// An options struct described once. A struct that declares
//
//   template <class V> static void describe(V& v) {
//     v("sigma_hit", &Options::sigma_hit, "m", "std of a hit around the nearest obstacle");
//     ...
//   }
//
// lists each field once, in declaration order, with its name, unit ("" for none) and doc. Every
// other form of the options comes from that list by a visitor: the state files' layout
// (write_options / read_options below), the Python options classes and constructor keywords
// (bindings/options_class.hpp), and the field paths validation errors name ("beam.sigma_hit").
// Adding an option is one line in describe() plus its use.
//
// Field types: double, int, std::uint64_t, bool, an enum with OptionEnum names, or another
// described struct (a nested group, written and bound through its own describe()).
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "probslam/core/state_file.hpp"

namespace probslam {

/// The names of an enum option's values, index = the enum's underlying value, as users write
/// them: specialise with `static constexpr std::array<const char*, N> names`.
template <class E>
struct OptionEnum;

template <class T, class = void>
struct IsDescribed : std::false_type {};
/// A struct with a describe() (its visitor accepted with any field type).
template <class T>
struct IsDescribed<T, std::void_t<decltype(&T::template describe<int>)>> : std::true_type {};

template <class E, class = void>
struct IsOptionEnum : std::false_type {};
template <class E>
struct IsOptionEnum<E, std::void_t<decltype(OptionEnum<E>::names)>> : std::true_type {};

/// Runs `validate()` of a nested options struct, its error prefixed by the field's name
/// ("odometry.alpha1 must be ..."), so a message gives the whole path to the bad field.
template <class Group>
void validate_group(const Group& group, const std::string& name) {
  try {
    group.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(name + "." + e.what());
  }
}

template <class Options>
void write_options(StateWriter& w, const Options& o);
template <class Options>
void read_options(StateReader& r, Options& o);

namespace options_detail {

template <class T>
void write_value(StateWriter& w, const T& v) {
  if constexpr (IsDescribed<T>::value) {
    write_options(w, v);
  } else if constexpr (std::is_same_v<T, double>) {
    w.f64(v);
  } else if constexpr (std::is_same_v<T, int>) {
    w.i32(v);
  } else if constexpr (std::is_same_v<T, std::uint64_t>) {
    w.u64(v);
  } else if constexpr (std::is_same_v<T, bool>) {
    w.boolean(v);
  } else {
    static_assert(IsOptionEnum<T>::value, "an option field must be double, int, uint64, bool, an enum or a group");
    w.u8(static_cast<std::uint8_t>(v));
  }
}

template <class T>
void read_value(StateReader& r, T& v, const char* name) {
  if constexpr (IsDescribed<T>::value) {
    read_options(r, v);
  } else if constexpr (std::is_same_v<T, double>) {
    v = r.f64();
  } else if constexpr (std::is_same_v<T, int>) {
    v = r.i32();
  } else if constexpr (std::is_same_v<T, std::uint64_t>) {
    v = r.u64();
  } else if constexpr (std::is_same_v<T, bool>) {
    v = r.boolean();
  } else {
    const std::uint8_t k = r.u8();
    if (k >= OptionEnum<T>::names.size())
      r.fail(std::string(name) + " holds an unknown value " + std::to_string(k));
    v = static_cast<T>(k);
  }
}

template <class Options>
struct Writer {
  StateWriter& w;
  const Options& o;
  template <class M>
  void operator()(const char*, M Options::*member, const char*, const char*) {
    write_value(w, o.*member);
  }
};

template <class Options>
struct Reader {
  StateReader& r;
  Options& o;
  template <class M>
  void operator()(const char* name, M Options::*member, const char*, const char*) {
    read_value(r, o.*member, name);
  }
};

}  // namespace options_detail

/// The fields of `o` in describe()'s order (groups inline), as the state files hold them.
template <class Options>
void write_options(StateWriter& w, const Options& o) {
  options_detail::Writer<Options> v{w, o};
  Options::describe(v);
}

/// What write_options wrote, the values as saved (the owner's constructor validates them; an
/// enum beyond its names is refused here).
template <class Options>
void read_options(StateReader& r, Options& o) {
  options_detail::Reader<Options> v{r, o};
  Options::describe(v);
}

}  // namespace probslam
