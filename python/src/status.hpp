// How the Python modules report failures: as the facemorph.Error subclass of the status (the C API's
// fm_status, the library's ErrorCode: one numbering), carrying the library's message unchanged.
#pragma once

#include "format/error.hpp"

#include <pybind11/pybind11.h>

#include <exception>
#include <string>
#include <utility>

namespace facemorph::python {

namespace py = pybind11;

// A status other than FM_OK with the calling thread's message (fm_last_error_message), carried out
// of code that ran without the GIL.
struct StatusError : std::exception {
  StatusError(int code, std::string message) : code(code), message(std::move(message)) {}
  const char* what() const noexcept override { return message.c_str(); }
  int code;
  std::string message;
};

// Sets the Python error: facemorph.errors._from_status(code, message), the class by code.
inline void set_status_error(int code, const std::string& message) {
  // Held for the interpreter's life (never released: a translator may run until it ends).
  static PyObject* factory = py::object(py::module_::import("facemorph.errors").attr("_from_status")).release().ptr();
  // Messages name files, whose names need not be UTF-8.
  py::object text =
      py::reinterpret_steal<py::object>(PyUnicode_DecodeUTF8(message.data(), static_cast<Py_ssize_t>(message.size()), "replace"));
  if (!text) return;
  PyObject* error = PyObject_CallFunction(factory, "iO", code, text.ptr());
  if (error == nullptr) return;  // the factory's own exception stands
  PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(error)), error);
  Py_DECREF(error);
}

// Translates StatusError and facemorph::Error (the encoder's, and the decoder internals') into
// facemorph.Error subclasses. Called once from each module's init.
inline void register_status_errors() {
  py::module_::import("facemorph.errors");  // fail at import, not at the first error, if it is missing
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StatusError& e) {
      set_status_error(e.code, e.message);
    } catch (const facemorph::Error& e) {
      set_status_error(static_cast<int>(e.code()), e.what());
    }
  });
}

}  // namespace facemorph::python
