#include "exceptions.hpp"

#include <cstring>
#include <exception>
#include <new>
#include <stdexcept>
#include <system_error>

#include "probslam/core/check.hpp"

namespace probslam::bindings {

namespace py = pybind11;

namespace {

void set_error(PyObject* type, const char* message) {
  PyObject* text = PyUnicode_DecodeUTF8(message, static_cast<Py_ssize_t>(std::strlen(message)), "backslashreplace");
  if (!text) {  // decoding cannot fail with backslashreplace; keep a message all the same
    PyErr_Clear();
    PyErr_SetString(type, "(unprintable message)");
    return;
  }
  PyErr_SetObject(type, text);
  Py_DECREF(text);
}

}  // namespace

py::str escaped_text(const std::string& s) {
  PyObject* o = PyUnicode_DecodeUTF8(s.data(), static_cast<Py_ssize_t>(s.size()), "backslashreplace");
  if (o == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(o);
}

void register_exception_translator() {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const py::error_already_set&) {
      throw;  // a Python error already: pybind11 restores it
    } catch (const py::builtin_exception&) {
      throw;  // py::value_error and friends, raised by the bindings with ASCII texts
    } catch (const std::bad_alloc&) {
      set_error(PyExc_MemoryError, "out of memory");
    } catch (const std::system_error& e) {  // e.g. a worker thread that could not be started
      set_error(PyExc_RuntimeError, e.what());
    } catch (const FileNotFound& e) {  // before its base, std::invalid_argument
      set_error(PyExc_FileNotFoundError, e.what());
    } catch (const std::invalid_argument& e) {
      set_error(PyExc_ValueError, e.what());
    } catch (const std::domain_error& e) {
      set_error(PyExc_ValueError, e.what());
    } catch (const std::length_error& e) {
      set_error(PyExc_ValueError, e.what());
    } catch (const std::out_of_range& e) {
      set_error(PyExc_IndexError, e.what());
    } catch (const std::range_error& e) {
      set_error(PyExc_ValueError, e.what());
    } catch (const std::overflow_error& e) {
      set_error(PyExc_OverflowError, e.what());
    } catch (const std::exception& e) {
      set_error(PyExc_RuntimeError, e.what());
    }
  });
}

}  // namespace probslam::bindings
