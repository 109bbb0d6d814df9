#pragma once
#include <pybind11/pybind11.h>

namespace probslam::bindings {

/// Translates the C++ library's exceptions into Python's (std::invalid_argument -> ValueError,
/// std::runtime_error -> RuntimeError, std::bad_alloc -> MemoryError, ...) with the message's
/// bytes that are not UTF-8 escaped, so a parser error quoting a corrupt file's text still
/// reaches Python as the usual ValueError("file:line: ...") and never as UnicodeDecodeError.
void register_exception_translator();

/// Text from a file (a skipped line's reason, a PARAM value) as a Python str: bytes that are not
/// UTF-8 become \xNN escapes rather than a UnicodeDecodeError.
pybind11::str escaped_text(const std::string& s);

}  // namespace probslam::bindings
