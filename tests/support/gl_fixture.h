// The GL context shared by the GL tests: created once; when there is none, tests skip with a
// message, unless BLOOMREF_REQUIRE_GL is set (CI), where a missing GL path is a failure.
#pragma once

#include <catch2/catch.hpp>
#include <memory>

#include "bloomref/gpu/context.h"

namespace bloomref::test {

inline gpu::GlContext* gl_context() {
  static std::unique_ptr<gpu::GlContext> ctx;
  static std::string why;
  static bool tried = false;
  if (!tried) {
    tried = true;
    try {
      ctx = gpu::GlContext::create();
    } catch (const gpu::GlUnavailable& e) {
      why = e.what();
    }
  }
  if (!ctx) {
    if (gpu::gl_required()) FAIL("BLOOMREF_REQUIRE_GL is set but the GL path is unavailable: " << why);
    WARN("GL path unavailable, GL test skipped: " << why);
  }
  return ctx.get();
}

}  // namespace bloomref::test
