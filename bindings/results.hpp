#pragma once
// Result structs as read-only Python classes. Each class lists its attributes in `_fields`, so one
// generic to_dict() (for JSON files), __eq__ and __repr__ serve every result class.
#include <string>
#include <utility>

#include "common.hpp"

namespace pickplan::bind {

// A value as to_dict gives it: results as dicts, lists and tuples of results as lists of dicts.
inline py::object plain_value(const py::handle& v) {
  if (py::hasattr(v, "_fields") && py::hasattr(v, "to_dict")) return v.attr("to_dict")();
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
    py::list out;
    for (const auto& item : v) out.append(plain_value(item));
    return std::move(out);
  }
  return py::reinterpret_borrow<py::object>(v);
}

inline py::dict result_to_dict(const py::object& self) {
  py::dict d;
  for (const auto& name : self.attr("_fields")) d[name] = plain_value(self.attr(name));
  return d;
}

// Field by field, arrays by their values (numpy.array_equal): results compare like the dicts they
// replaced. Another type compares unequal.
inline bool result_equal(const py::object& self, const py::object& other) {
  if (!py::type::of(self).is(py::type::of(other))) return false;
  const py::object array_equal = py::module_::import("numpy").attr("array_equal");
  for (const auto& name : self.attr("_fields")) {
    const py::object a = self.attr(name), b = other.attr(name);
    const bool same =
        py::isinstance<py::array>(a) || py::isinstance<py::array>(b) ? array_equal(a, b).cast<bool>() : a.equal(b);
    if (!same) return false;
  }
  return true;
}

// Arrays and long lists by their size only: a repr stays one readable line.
inline std::string field_repr(const py::handle& v) {
  if (py::isinstance<py::array>(v)) return "array" + shape_str(py::reinterpret_borrow<py::array>(v));
  if (py::isinstance<py::list>(v) && py::len(v) > 6) return "[" + std::to_string(py::len(v)) + " items]";
  return py::repr(v).cast<std::string>();
}

inline std::string result_repr(const py::object& self) {
  std::string s = py::str(py::type::of(self).attr("__name__")).cast<std::string>() + "(";
  bool first = true;
  for (const auto& name : self.attr("_fields")) {
    s += (first ? "" : ", ") + name.cast<std::string>() + "=" + field_repr(self.attr(name));
    first = false;
  }
  return s + ")";
}

// py::class_ with read-only fields recorded in `_fields`:
//   result_class<IkSolution>(m, "IkSolution").field("q", &IkSolution::q).field(...);
// Eigen members come out as read-only numpy views of the result (no copy).
template <typename T, typename... Options>
class result_class : public py::class_<T, Options...> {
 public:
  result_class(py::handle scope, const char* name, const char* doc = "") : py::class_<T, Options...>(scope, name, doc) {
    this->attr("_fields") = py::tuple();
    this->def("to_dict", &result_to_dict, "The fields as a dict (nested results as dicts).");
    this->def("__repr__", &result_repr);
    this->def("__eq__", &result_equal);
  }

  template <typename D>
  result_class& field(const char* name, const D T::* member) {
    this->def_readonly(name, member);
    return add(name);
  }

  // A field computed from the struct (a renamed or converted member).
  template <typename Getter>
  result_class& computed(const char* name, Getter&& getter) {
    this->def_property_readonly(name, std::forward<Getter>(getter));
    return add(name);
  }

 private:
  result_class& add(const char* name) {
    py::list names(this->attr("_fields"));
    names.append(name);
    this->attr("_fields") = py::tuple(names);
    return *this;
  }
};

}  // namespace pickplan::bind
