// bloomref GPU — a headless OpenGL 4.3+ core context through EGL. Only gpu/ includes EGL or GL.
//
// Device choice (docs/design.md, "GL path"): the EGL device platform, preferring a hardware
// device, else Mesa's software device (llvmpipe); else the surfaceless platform.
// BLOOMREF_EGL_DEVICE overrides: a device index ("0", "1"...), "software", "hardware" or
// "surfaceless". Every EGL/GL call is checked; GL_KHR_debug messages of type error are errors.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bloomref/error.h"

namespace bloomref::gpu {

/// No EGL device, display or context could be had (the CLI exits 3; tests skip, or fail in CI
/// where BLOOMREF_REQUIRE_GL=1).
class GlUnavailable : public Error {
 public:
  using Error::Error;
};

/// A GL call or shader failed (a bug or a driver limit, not a missing GPU).
class GlError : public Error {
 public:
  using Error::Error;
};

struct ContextInfo {
  std::string platform;  ///< "device" or "surfaceless"
  std::string device;    ///< e.g. "software (EGL_MESA_device_software)" or "hardware"
  std::string vendor, renderer, version, glsl_version;
  bool software = false;
};

class GlContext {
 public:
  /// Creates and makes current a context on the calling thread. Throws GlUnavailable.
  static std::unique_ptr<GlContext> create();
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  const ContextInfo& info() const { return info_; }
  /// Throws GlError if GL reported an error (glGetError or a KHR_debug error message) since the
  /// last check; `what` names the call site.
  void check(const char* what);
  /// Debug messages collected since the last call (errors are thrown by check()).
  std::vector<std::string> take_messages();

  struct Impl;

 private:
  explicit GlContext(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  ContextInfo info_;
};

/// True when BLOOMREF_REQUIRE_GL is set to a non-empty value other than "0".
bool gl_required();

}  // namespace bloomref::gpu
