// Preconditions at public entry points, as exceptions (COLMAP's THROW_CHECK
// discipline): misuse gets an Error naming what was wrong instead of
// undefined behaviour. Internal hot paths stay check-free.
#pragma once

#include <cstddef>
#include <initializer_list>

#include "linecloud/util/error.h"

namespace linecloud {

// A minimal solver's sample: `out` non-null and every input span at least
// `n` long (the solvers read exactly their first n elements).
template <typename Out, typename... Spans>
void CheckMinimalSample(const char* solver, size_t n, const Out* out, const Spans&... spans) {
  if (out == nullptr) Fail("{}: no output given (null pointer)", solver);
  for (const size_t size : {spans.size()...}) {
    if (size < n) Fail("{}: needs {} correspondences, got a span of {}", solver, n, size);
  }
}

}  // namespace linecloud
