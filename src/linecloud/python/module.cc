// linecloud._core: the C++ library for Python (pybind11). The package
// `linecloud` (python/linecloud/__init__.py) re-exports it.
//
// Errors: a file the system cannot open, read or write raises OSError (with
// errno: FileNotFoundError, PermissionError, ...); every other bad input
// raises ValueError with the library's message (which names the file, field
// or argument); a wrong Python type raises TypeError.
#include <string>

#include <pybind11/pybind11.h>

#include "linecloud/python/bindings.h"
#include "linecloud/util/error.h"
#include "linecloud/version.h"

namespace py = pybind11;

PYBIND11_MODULE(_core, m) {
  m.doc() = "linecloud: privacy-preserving image-based localization (Speciale et al., CVPR 2019)";
  m.attr("__version__") = std::to_string(LINECLOUD_VERSION_MAJOR) + "." +
                          std::to_string(LINECLOUD_VERSION_MINOR) + "." +
                          std::to_string(LINECLOUD_VERSION_PATCH);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const linecloud::FileError& e) {
      py::object error =
          py::reinterpret_borrow<py::object>(PyExc_OSError)(e.error_number(), e.what());
      PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(error.ptr())), error.ptr());
    } catch (const linecloud::Error& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  linecloud::python::BindLineCloud(m);
  linecloud::python::BindLocalizer(m);
  linecloud::python::BindEstimation(m);
  linecloud::python::BindPrivacy(m);
}
