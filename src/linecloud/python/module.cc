// linecloud._core: the C++ library for Python (pybind11). The package
// `linecloud` (python/linecloud/__init__.py) re-exports it.
//
// Errors: a file the system cannot open, read or write raises OSError (with
// errno: FileNotFoundError, PermissionError, ...); every other bad input
// raises ValueError with the library's message (which names the file, field
// or argument); a wrong Python type raises TypeError.
//
// Progress and warnings (util/log.h) go to stdout / stderr unless set_log_sink hands them to a
// Python callable.
#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <utility>

#include <pybind11/pybind11.h>

#include "linecloud/python/bindings.h"
#include "linecloud/util/error.h"
#include "linecloud/util/log.h"
#include "linecloud/version.h"

namespace py = pybind11;

namespace linecloud::python {
namespace {

std::atomic<bool> exiting{false};
std::atomic<int> running{0};          // long calls running without the GIL, not parked
thread_local int released_depth = 0;  // this thread's GilReleased scopes

bool InterpreterExiting() {
#if PY_VERSION_HEX >= 0x030D0000
  return exiting || Py_IsFinalizing();
#else
  return exiting || _Py_IsFinalizing();
#endif
}

}  // namespace

void ParkIfInterpreterExiting() {
  if (!InterpreterExiting()) return;
  if (released_depth > 0) --running;  // counted by its outermost GilReleased: parked now
  for (;;) std::this_thread::sleep_for(std::chrono::hours(1));
}

bool PythonSignalRaised() {
  ParkIfInterpreterExiting();
  py::gil_scoped_acquire gil;
  return PyErr_CheckSignals() != 0;
}

void WaitForLongCallsToPark() {
  exiting = true;
  GilReleased release;  // (this thread's own release is not counted as a call)
  --running;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (running > 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ++running;
  exiting = false;  // the GIL is taken back below; later calls at exit park in finalization
}

GilReleased::GilReleased() : state_(PyEval_SaveThread()), outer_(released_depth++ == 0) {
  if (outer_) ++running;
}

GilReleased::~GilReleased() {
  ParkIfInterpreterExiting();
  --released_depth;
  if (outer_) --running;
  PyEval_RestoreThread(state_);
}

}  // namespace linecloud::python

namespace {

// The library's log sink as a Python callable sink(level, line): called with the GIL taken (the
// library calls it from threads that released it); an exception it raises is reported as
// unraisable and the work goes on. None restores the default (stdout / stderr).
void SetLogSink(linecloud::python::SinkArg sink) {
  linecloud::LogSink cpp;
  if (!sink.is_none()) {
    if (!PyCallable_Check(sink.ptr())) {
      throw py::type_error("set_log_sink: sink must be a callable sink(level, line) or None");
    }
    std::shared_ptr<py::object> held(new py::object(std::move(sink)), [](py::object* object) {
      linecloud::python::ParkIfInterpreterExiting();
      py::gil_scoped_acquire gil;
      delete object;
    });
    cpp = [held](linecloud::LogLevel level, std::string_view line) {
      linecloud::python::ParkIfInterpreterExiting();
      py::gil_scoped_acquire gil;
      try {
        (*held)(std::string(linecloud::LogLevelName(level)), std::string(line));
      } catch (py::error_already_set& error) {
        error.discard_as_unraisable("linecloud's log sink");
      }
    };
  }
  // The sink's lock is never held while a sink runs, so it is taken with the GIL held; the sink
  // replaced is dropped here, its Python object with the GIL.
  linecloud::SetLogSink(std::move(cpp));
}

}  // namespace

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
  m.def("set_log_sink", &SetLogSink, py::arg("sink"),
        "Where the library's progress lines and warnings go: sink(level, line) with level "
        "'progress' or 'warning'; `lambda level, line: None` silences them; None restores the "
        "default (progress to stdout, warnings to stderr). One sink for the process.");
  // The sink holds a Python object: drop it before the interpreter goes.
  py::module_::import("atexit").attr("register")(py::cpp_function([] { SetLogSink(py::none()); }));
  // Daemon threads inside long calls park before the interpreter and the library go (bindings.h).
  py::module_::import("atexit").attr("register")(
      py::cpp_function([] { linecloud::python::WaitForLongCallsToPark(); }));
  linecloud::python::BindLineCloud(m);
  linecloud::python::BindLocalizer(m);
  linecloud::python::BindEstimation(m);
  linecloud::python::BindPrivacy(m);
  linecloud::python::BindMapping(m);
}
