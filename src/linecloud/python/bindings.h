// The parts of `linecloud._core`, one function per file that adds them to the
// module (module.cc calls them in order).
#pragma once

#include <pybind11/pybind11.h>

namespace linecloud::python {

void BindLineCloud(pybind11::module_& m);   // LineCloud, lift, read_colmap_model
void BindLocalizer(pybind11::module_& m);   // Localizer
void BindEstimation(pybind11::module_& m);  // estimate_pose, solve, methods
void BindPrivacy(pybind11::module_& m);     // attack, audit

}  // namespace linecloud::python
