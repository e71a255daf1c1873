// The parts of `linecloud._core`, one function per file that adds them to the
// module (module.cc calls them in order).
#pragma once

#include <pybind11/pybind11.h>

namespace linecloud::python {

// Exit while a daemon thread is inside a long call. A thread that released the GIL must not take
// it back once the interpreter exits: CPython ends such a thread with pthread_exit, whose
// unwinding through the noexcept destructor of pybind11's gil_scoped_release aborted the process
// (SIGABRT). And it must not still be computing while exit() runs the library's static
// destructors (a SIGSEGV in a solver). So: an atexit hook (registered by the module) marks the
// exit and waits, GIL released, up to 2 s for every long call to reach a point where it parks:
// its next poll (RANSAC polls for Ctrl-C) or its end. A parked thread sleeps until the process
// ends. A call that polls nothing for longer than that can still be inside the library at exit.
void ParkIfInterpreterExiting();
void WaitForLongCallsToPark();  // the atexit hook's wait

// A long call's should_stop (RANSAC polls it): true when a Python signal handler raised (Ctrl-C),
// the exception left set for the caller to raise; parks the thread when the interpreter exits.
bool PythonSignalRaised();

// The GIL released around a long call and taken back after it (pybind11's gil_scoped_release),
// counting the call as running until it returns or parks.
class GilReleased {
 public:
  GilReleased();
  ~GilReleased();
  GilReleased(const GilReleased&) = delete;
  GilReleased& operator=(const GilReleased&) = delete;

 private:
  PyThreadState* state_;
  bool outer_;  // the thread's outermost release (the one counted)
};

// Arguments that take several Python types: any object, named in the signatures help() and the
// stubs show by what it may be (pybind11 shows a py::handle as "handle").
#define LINECLOUD_PY_ARG(Name, text)                                      \
  class Name : public pybind11::object {                                  \
   public:                                                                \
    static bool Any(PyObject*) { return true; }                           \
    PYBIND11_OBJECT_DEFAULT(Name, pybind11::object, Any)                  \
    static constexpr auto kTypeName = pybind11::detail::const_name(text); \
  };
LINECLOUD_PY_ARG(ImageArg, "str | os.PathLike | bytes | BinaryIO | numpy.ndarray | list")
LINECLOUD_PY_ARG(CameraArg, "dict | str | pycolmap.Camera | list")
LINECLOUD_PY_ARG(ArrayArg, "numpy.ndarray | list")
LINECLOUD_PY_ARG(QueryArg, "dict")
LINECLOUD_PY_ARG(CloudArg, "LineCloud | str | os.PathLike")
LINECLOUD_PY_ARG(PathArg, "str | os.PathLike | None")
LINECLOUD_PY_ARG(ModelArg, "str | os.PathLike | pycolmap.Reconstruction")
LINECLOUD_PY_ARG(FlagArg, "bool | None")
LINECLOUD_PY_ARG(OptionsArg, "dict | bool | None")
LINECLOUD_PY_ARG(VectorArg, "numpy.ndarray | list | None")
LINECLOUD_PY_ARG(PosesArg, "list[Pose | dict] | None")
LINECLOUD_PY_ARG(SinkArg, "Callable[[str, str], None] | None")
#undef LINECLOUD_PY_ARG

void BindLineCloud(pybind11::module_& m);   // LineCloud, lift, read_colmap_model
void BindLocalizer(pybind11::module_& m);   // Localizer
void BindEstimation(pybind11::module_& m);  // estimate_pose, solve, methods
void BindPrivacy(pybind11::module_& m);     // attack, audit
void BindMapping(pybind11::module_& m);     // map

}  // namespace linecloud::python

namespace pybind11::detail {
template <typename T>
requires requires { T::kTypeName; }
struct handle_type_name<T> {
  static constexpr auto name = T::kTypeName;
};
}  // namespace pybind11::detail
