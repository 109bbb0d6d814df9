#pragma once
// Python options classes and constructor keywords from a C++ options struct's describe()
// (core/options_description.hpp): one class per struct, nested groups as attributes, each field
// a property with its unit and doc in help(); values checked by type as they are set (TypeError
// naming the field's path), ranges by the struct's validate() (ValueError naming the path).
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <type_traits>
#include <typeindex>
#include <utility>

#include "args.hpp"
#include "probslam/core/options_description.hpp"

namespace probslam::bindings {

namespace options_detail {

/// A field's value from Python, errors naming `path`. A group takes an instance of its options
/// class or a dict of its fields.
template <class T>
T field_from_py(py::handle v, const std::string& path);

template <class T>
void set_fields(T& o, py::handle values, const std::string& prefix, const char* owner);

template <class M>
void assign_field(M& field, py::handle v, const std::string& path);

template <class T>
T field_from_py(py::handle v, const std::string& path) {
  if constexpr (IsDescribed<T>::value) {
    if (py::isinstance<T>(v)) return v.cast<T>();
    if (!py::isinstance<py::dict>(v))
      throw py::type_error(path + ": expected " + with_article(py::str(py::type::of<T>().attr("__name__"))) +
                           " or a dict of its fields, got " + type_name_of(v));
    T group;
    set_fields(group, v, path + ".", path.c_str());
    return group;
  } else if constexpr (std::is_same_v<T, double>) {
    return RealArg{py::reinterpret_borrow<py::object>(v)}.get(path.c_str());
  } else if constexpr (std::is_same_v<T, int>) {
    return IntArg{py::reinterpret_borrow<py::object>(v)}.get(path.c_str());
  } else if constexpr (std::is_same_v<T, std::uint64_t>) {
    return UInt64Arg{py::reinterpret_borrow<py::object>(v)}.get(path.c_str());
  } else if constexpr (std::is_same_v<T, long>) {
    return static_cast<long>(index_value(v, path));
  } else if constexpr (std::is_same_v<T, bool>) {
    return BoolArg{py::reinterpret_borrow<py::object>(v)}.get(path.c_str());
  } else {
    const std::string s = StrArg{py::reinterpret_borrow<py::object>(v)}.get(path.c_str());
    const auto& names = OptionEnum<T>::names;
    std::string listed;
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (s == names[k]) return static_cast<T>(k);
      listed += std::string(k ? ", " : "") + "\"" + names[k] + "\"";
    }
    throw py::value_error(path + " must be one of " + listed + ", got \"" + s + "\"");
  }
}

/// A field's value as Python shows it (an enum by its name, a group as its options class).
template <class T>
py::object field_to_py(const T& v) {
  if constexpr (IsOptionEnum<T>::value) return py::str(OptionEnum<T>::names[static_cast<std::size_t>(v)]);
  else return py::cast(v);
}

/// The field names of T, in order.
template <class T>
struct Names {
  std::set<std::string> names;
  template <class M>
  void operator()(const char* name, M T::*, const char*, const char*) { names.insert(name); }
};

/// Sets the fields of `o` named in the mapping `values` (TypeError for a name T does not have).
template <class T>
struct Setter {
  T& o;
  py::handle values;
  const std::string& prefix;
  template <class M>
  void operator()(const char* name, M T::*member, const char*, const char*) {
    const py::str key(name);
    if (!values.contains(key)) return;
    assign_field(o.*member, values[key], prefix + name);
  }
};

/// `field = v` for a value from Python, errors naming `path`: a group given a dict changes the
/// fields it names and keeps the others (on a copy, so a refused value changes nothing).
template <class M>
void assign_field(M& field, py::handle v, const std::string& path) {
  if constexpr (IsDescribed<M>::value) {
    if (py::isinstance<py::dict>(v)) {
      M group = field;
      set_fields(group, v, path + ".", path.c_str());
      field = group;
      return;
    }
  }
  field = field_from_py<M>(v, path);
}

template <class T>
void set_fields(T& o, py::handle values, const std::string& prefix, const char* owner) {
  Names<T> known;
  T::describe(known);
  for (auto item : py::reinterpret_borrow<py::dict>(values)) {
    const std::string key = py::str(item.first);
    if (!known.names.count(key))
      throw py::type_error(std::string(owner) + " got an unexpected keyword argument '" + key + "'");
  }
  Setter<T> set{o, values, prefix};
  T::describe(set);
}

/// "name=value, ..." of every field, groups nested.
template <class T>
struct Repr {
  const T& o;
  std::string out;
  template <class M>
  void operator()(const char* name, M T::*member, const char*, const char*) {
    out += std::string(out.empty() ? "" : ", ") + name + "=" + std::string(py::repr(field_to_py(o.*member)));
  }
};

/// Whether two structs agree on every field (doubles compared by value: NaN differs).
template <class T>
struct Equal {
  const T& a;
  const T& b;
  bool same = true;
  template <class M>
  void operator()(const char*, M T::*member, const char*, const char*) {
    if constexpr (IsDescribed<M>::value) {
      Equal<M> inner{a.*member, b.*member};
      M::describe(inner);
      same = same && inner.same;
    } else {
      same = same && a.*member == b.*member;
    }
  }
};

/// "name (unit): doc", a field's line in help() and in its class's docstring.
inline std::string field_doc(const char* name, const char* unit, const char* text) {
  return std::string(name) + (*unit ? std::string(" (") + unit + ")" : "") + ": " + text;
}

/// {name: value} of every field (groups as their options classes).
template <class T>
struct ToDict {
  const T& o;
  py::dict d;
  template <class M>
  void operator()(const char* name, M T::*member, const char*, const char*) {
    d[name] = field_to_py(o.*member);
  }
};

/// Where a group reached through its options sits in them (`o.frontend.filter` is at
/// "frontend.filter."), so that its setters name a field's whole path as the constructors do
/// (the group's class alone knows only the leaf). Keyed by the group's address and type; an
/// entry lives as long as the group's Python object, which keeps its options alive (a weak
/// reference's callback removes it), so a freed address never inherits a stale path.
using GroupKey = std::pair<const void*, std::type_index>;
inline std::map<GroupKey, std::string>& group_paths() {
  static std::map<GroupKey, std::string> paths;  // guarded by the GIL
  return paths;
}

/// The path prefix of `o` ("" for options not reached through others).
template <class T>
std::string path_prefix(const T& o) {
  const auto it = group_paths().find(GroupKey{&o, std::type_index(typeid(T))});
  return it == group_paths().end() ? std::string() : it->second;
}

/// Group `group` of the options object `parent`, by reference, its path recorded as `path`.
template <class M>
py::object group_of(py::handle parent, M& group, const std::string& path) {
  py::object child = py::cast(&group, py::return_value_policy::reference_internal, parent);
  const GroupKey key{&group, std::type_index(typeid(M))};
  if (group_paths().emplace(key, path).second) {
    py::weakref(child, py::cpp_function([key](py::handle ref) {
      group_paths().erase(key);
      ref.dec_ref();
    })).release();
  }
  return child;
}

/// Defines each field as a property: a group by reference (`o.beam.z_hit = 0.9` sets it), the
/// others checked by type as they are set, errors naming the field's path; a report's fields
/// (writable false) read-only.
template <class T>
struct Properties {
  py::class_<T>& c;
  std::string& doc;
  bool writable;
  template <class M>
  void operator()(const char* name, M T::*member, const char* unit, const char* text) {
    const std::string field = field_doc(name, unit, text);
    doc += "\n    " + field;
    auto get = [member](const T& o) { return field_to_py(o.*member); };
    if (!writable) {
      c.def_property_readonly(name, get, field.c_str());
      return;
    }
    auto set = [member, n = std::string(name)](T& o, py::handle v) { assign_field(o.*member, v, path_prefix(o) + n); };
    if constexpr (IsDescribed<M>::value) {
      c.def_property(
          name, [member, n = std::string(name)](py::handle self) {
            T& o = self.cast<T&>();
            return group_of(self, o.*member, path_prefix(o) + n + ".");
          },
          set, field.c_str());
    } else {
      c.def_property(name, get, set, field.c_str());
    }
  }
};

/// "name: type = default" of each field, keyword-only parameters of a generated signature.
template <class T>
struct Signature {
  const T& o;
  std::string out;
  template <class M>
  void operator()(const char* name, M T::*member, const char*, const char*) {
    std::string type;
    if constexpr (IsDescribed<M>::value) type = py::str(py::type::of<M>().attr("__name__"));
    else if constexpr (std::is_same_v<M, double>) type = "float";
    else if constexpr (std::is_same_v<M, bool>) type = "bool";
    else if constexpr (IsOptionEnum<M>::value) type = "str";
    else type = "int";
    out += std::string(", ") + name + ": " + type + " = " + default_text(o.*member);
  }
  /// A group's default is its class's (`...` here: the class shows it), an infinity math.inf
  /// (what the stub imports), anything else its repr.
  template <class M>
  static std::string default_text(const M& v) {
    if constexpr (IsDescribed<M>::value) return "...";
    else if constexpr (std::is_same_v<M, double>) {
      if (std::isinf(v)) return v > 0 ? "math.inf" : "-math.inf";
    }
    return py::repr(field_to_py(v));
  }
};

}  // namespace options_detail

/// ", name: type = default, ..." of T's fields at `defaults` (the signature a constructor that
/// takes them by keyword shows; pybind11 sees only **kwargs).
template <class T>
std::string field_parameters(const T& defaults = T{}) {
  options_detail::Signature<T> s{defaults, {}};
  T::describe(s);
  return s.out;
}

/// "<head>options: Optional[<T's class>] = None<after><T's fields>) -> <returns>\n\n<doc>": the
/// signature line of a call taking T as `options` and its fields by keyword (pybind11 would show
/// **kwargs); head ends with the parameters before options ("optimize(graph: ..., *, ").
template <class T>
std::string options_signature_line(const std::string& head, const std::string& after, const std::string& returns,
                                   const std::string& doc) {
  const std::string type = py::str(py::type::of<T>().attr("__name__"));
  return head + "options: Optional[" + type + "] = None" + after + field_parameters<T>() + ") -> " + returns +
         "\n\n" + doc;
}

/// The signature line of a constructor `owner(<before>options=None<after>, **fields)`.
template <class T>
std::string options_init_signature(const std::string& owner, const std::string& before, const std::string& after = "") {
  return options_signature_line<T>("__init__(self: " + owner + ", " + before, after, "None",
                                   "See the class docstring: a field given by keyword replaces options' field.");
}

/// `o` with the fields named in `kwargs` set (a copy; the struct's validate() not run).
template <class T>
T options_with(T o, const py::kwargs& kwargs, const char* owner) {
  options_detail::set_fields(o, kwargs, "", owner);
  return o;
}

/// What a constructor `Owner(..., *, options=None, **fields)` runs with: `options` (None: T's
/// defaults; else a T, TypeError naming `options` otherwise) with the fields named in `fields`
/// replaced (the struct's validate() not run: the owner's constructor runs it).
template <class T>
T options_arg(py::handle options, const py::kwargs& fields, const char* owner) {
  T base;
  if (!options.is_none()) base = ClassArg<T>{py::reinterpret_borrow<py::object>(options)}.get("options");
  return options_with(base, fields, owner);
}

/// What every class made from a describe() has: {field: value} (as_dict), == by fields, a repr
/// of every field, pickling by fields (rebuilt through the fields' setters), no hash (mutable).
template <class T>
void define_by_fields(py::class_<T>& c, const char* name) {
  auto to_dict = [](const T& o) {
    options_detail::ToDict<T> d{o, {}};
    T::describe(d);
    return d.d;
  };
  c.def("as_dict", to_dict, "{field: value} of every field (to write as JSON or a table row).")
      .def("__eq__", [](const T& a, py::handle b) {
        if (!py::isinstance<T>(b)) return false;
        options_detail::Equal<T> eq{a, b.cast<const T&>()};
        T::describe(eq);
        return eq.same;
      }, py::arg("other"))
      .def("__repr__", [name](const T& o) {
        options_detail::Repr<T> r{o, {}};
        T::describe(r);
        return std::string(name) + "(" + r.out + ")";
      })
      .def(py::pickle(to_dict, [name](const py::dict& d) { return options_with(T{}, py::kwargs(d), name); }));
  c.attr("__hash__") = py::none();
}

/// The Python class of a described struct T with a property per field (writable or read-only)
/// and the docstring `head` followed by "Fields:" and each field's "name (unit): doc".
template <class T>
py::class_<T> described_class(py::module_& m, const char* name, const std::string& head, bool writable) {
  py::class_<T> c(m, name);
  std::string doc = head + "\nFields:";
  options_detail::Properties<T> properties{c, doc, writable};
  T::describe(properties);
  c.attr("__doc__") = doc;
  return c;
}

/// The Python class of options struct T: T(**fields) (validated), a property per field,
/// validate(), copy(), ==, repr and pickling by fields.
template <class T>
py::class_<T> bind_options(py::module_& m, const char* name, const std::string& summary) {
  py::class_<T> c = described_class<T>(
      m, name,
      summary + "\n\n" + name + "(**fields): every field has a default; unknown names raise TypeError,\n" +
          "values of the wrong type TypeError and out of range ValueError, naming the field's path.",
      true);
  const std::string params = field_parameters<T>();
  {
    py::options signatures;  // the keyword signatures are written from describe(), not **kwargs
    signatures.disable_function_signatures();
    c.def(py::init([name](const py::kwargs& kwargs) {
           T o = options_with(T{}, kwargs, name);
           o.validate();
           return o;
         }),
         ("__init__(self: " + std::string(name) + ", *" + params + ") -> None\n\nThe options, validated.").c_str())
        .def("replace", [name](const T& o, const py::kwargs& kwargs) {
          T r = options_with(o, kwargs, name);
          r.validate();
          return r;
        }, ("replace(self: " + std::string(name) + ", *" + params + ") -> " + name +
            "\n\nA validated copy with the fields named set (a group's dict sets the fields it names; a default\n"
            "shown is the struct's, a field not named keeps its value).").c_str());
  }
  c.def("validate", &T::validate, "ValueError naming the first field out of range by its path.")
      .def("copy", [](const T& o) { return T(o); }, "An independent copy.")
      .def("__copy__", [](const T& o) { return T(o); })
      .def("__deepcopy__", [](const T& o, py::handle) { return T(o); }, py::arg("memo"));
  define_by_fields(c, name);
  return c;
}

/// The Python class of a described report struct T (what a run measured: timings, memory): a
/// read-only property per field with its unit and doc, as_dict(), ==, repr and pickling.
template <class T>
py::class_<T> bind_report(py::module_& m, const char* name, const std::string& summary) {
  py::class_<T> c = described_class<T>(m, name, summary, false);
  define_by_fields(c, name);
  return c;
}

}  // namespace probslam::bindings
