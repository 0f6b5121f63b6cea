#include "bloomref/gpu/context.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <cstdlib>
#include <cstring>
#include <mutex>

namespace bloomref::gpu {

struct GlContext::Impl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::mutex m;
  std::vector<std::string> messages;
  std::vector<std::string> errors;
};

namespace {

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const std::size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

std::string egl_error_name(EGLint e) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "EGL error 0x%04x", e);
  return buf;
}

void GLAPIENTRY on_debug(GLenum, GLenum type, GLuint, GLenum severity, GLsizei, const GLchar* msg,
                         const void* user) {
  auto* impl = static_cast<GlContext::Impl*>(const_cast<void*>(user));
  std::lock_guard<std::mutex> lock(impl->m);
  (void)severity;  // compiler warnings can be "high"; only errors are errors
  if (type == GL_DEBUG_TYPE_ERROR || type == GL_DEBUG_TYPE_UNDEFINED_BEHAVIOR)
    impl->errors.emplace_back(msg);
  else
    impl->messages.emplace_back(msg);
}

struct Candidate {
  EGLDisplay display;
  std::string platform, device;
  bool software;
};

// The displays to try, in order of preference.
std::vector<Candidate> candidates() {
  std::vector<Candidate> out;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const char* override_env = std::getenv("BLOOMREF_EGL_DEVICE");
  const std::string want = override_env ? override_env : "";
  if (has_extension(client, "EGL_EXT_device_enumeration") &&
      has_extension(client, "EGL_EXT_platform_device") && want != "surfaceless") {
    EGLint n = 0;
    eglQueryDevicesEXT(0, nullptr, &n);
    std::vector<EGLDeviceEXT> devices(n);
    if (n > 0) eglQueryDevicesEXT(n, devices.data(), &n);
    std::vector<Candidate> hardware, software;
    for (EGLint i = 0; i < n; ++i) {
      const char* ext = eglQueryDeviceStringEXT(devices[i], EGL_EXTENSIONS);
      const bool sw = has_extension(ext, "EGL_MESA_device_software");
      if (!want.empty() && want != "software" && want != "hardware" && want != std::to_string(i))
        continue;
      if ((want == "software" && !sw) || (want == "hardware" && sw)) continue;
      EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
      if (d == EGL_NO_DISPLAY) continue;
      Candidate c{d, "device",
                  "device " + std::to_string(i) + (sw ? " (software, EGL_MESA_device_software)"
                                                      : " (hardware)"),
                  sw};
      (sw ? software : hardware).push_back(c);
    }
    out.insert(out.end(), hardware.begin(), hardware.end());
    out.insert(out.end(), software.begin(), software.end());
  }
  if ((want.empty() || want == "surfaceless") &&
      has_extension(client, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY,
                                            nullptr);
    if (d != EGL_NO_DISPLAY) out.push_back({d, "surfaceless", "surfaceless", false});
  }
  return out;
}

}  // namespace

bool gl_required() {
  const char* v = std::getenv("BLOOMREF_REQUIRE_GL");
  return v && *v && std::strcmp(v, "0") != 0;
}

GlContext::GlContext(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

GlContext::~GlContext() {
  if (impl_->display != EGL_NO_DISPLAY) {
    eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (impl_->context != EGL_NO_CONTEXT) eglDestroyContext(impl_->display, impl_->context);
    eglTerminate(impl_->display);
  }
}

std::unique_ptr<GlContext> GlContext::create() {
  std::string tried;
  for (const Candidate& c : candidates()) {
    auto impl = std::make_unique<Impl>();
    EGLint major = 0, minor = 0;
    if (!eglInitialize(c.display, &major, &minor)) {
      tried += "; " + c.device + ": eglInitialize failed (" + egl_error_name(eglGetError()) + ")";
      continue;
    }
    impl->display = c.display;
    if (!eglBindAPI(EGL_OPENGL_API)) {
      tried += "; " + c.device + ": no desktop OpenGL";
      eglTerminate(c.display);
      continue;
    }
    // Measured on llvmpipe/surfaceless: eglChooseConfig with only EGL_RENDERABLE_TYPE returns
    // zero configs, so ask for a pbuffer-capable config, or none at all (KHR_no_config_context);
    // the context is made current without surfaces (KHR_surfaceless_context) and renders to FBOs.
    const char* dext = eglQueryString(c.display, EGL_EXTENSIONS);
    EGLConfig config = nullptr;
    if (!has_extension(dext, "EGL_KHR_no_config_context")) {
      const EGLint attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                EGL_OPENGL_BIT, EGL_NONE};
      EGLint n = 0;
      if (!eglChooseConfig(c.display, attribs, &config, 1, &n) || n < 1) {
        tried += "; " + c.device + ": no OpenGL config";
        eglTerminate(c.display);
        impl->display = EGL_NO_DISPLAY;
        continue;
      }
    }
    const EGLint ctx_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
                                  EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                  EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                  EGL_CONTEXT_OPENGL_DEBUG, EGL_TRUE, EGL_NONE};
    impl->context = eglCreateContext(c.display, config, EGL_NO_CONTEXT, ctx_attribs);
    if (impl->context == EGL_NO_CONTEXT) {
      tried += "; " + c.device + ": no OpenGL 4.3 core context (" +
               egl_error_name(eglGetError()) + ")";
      eglTerminate(c.display);
      impl->display = EGL_NO_DISPLAY;
      continue;
    }
    if (!eglMakeCurrent(c.display, EGL_NO_SURFACE, EGL_NO_SURFACE, impl->context)) {
      tried += "; " + c.device + ": eglMakeCurrent failed (" + egl_error_name(eglGetError()) + ")";
      eglDestroyContext(c.display, impl->context);
      eglTerminate(c.display);
      impl->display = EGL_NO_DISPLAY;
      continue;
    }
    Impl* raw = impl.get();
    std::unique_ptr<GlContext> ctx(new GlContext(std::move(impl)));
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
    glDebugMessageCallback(on_debug, raw);
    ContextInfo& info = ctx->info_;
    info.platform = c.platform;
    info.device = c.device;
    info.software = c.software;
    auto str = [](GLenum e) {
      const GLubyte* s = glGetString(e);
      return std::string(s ? reinterpret_cast<const char*>(s) : "?");
    };
    info.vendor = str(GL_VENDOR);
    info.renderer = str(GL_RENDERER);
    info.version = str(GL_VERSION);
    info.glsl_version = str(GL_SHADING_LANGUAGE_VERSION);
    if (info.renderer.find("llvmpipe") != std::string::npos ||
        info.renderer.find("softpipe") != std::string::npos)
      info.software = true;
    ctx->check("context creation");
    return ctx;
  }
  throw GlUnavailable("no EGL device or context for OpenGL 4.3 core" +
                      (tried.empty() ? std::string(" (no EGL device or surfaceless platform)")
                                     : tried));
}

void GlContext::check(const char* what) {
  const GLenum e = glGetError();
  std::vector<std::string> errors;
  {
    std::lock_guard<std::mutex> lock(impl_->m);
    errors.swap(impl_->errors);
  }
  if (e == GL_NO_ERROR && errors.empty()) return;
  std::string msg = std::string("GL error at ") + what;
  if (e != GL_NO_ERROR) {
    char buf[32];
    std::snprintf(buf, sizeof buf, ": glGetError 0x%04x", e);
    msg += buf;
  }
  for (const std::string& s : errors) msg += "; " + s;
  throw GlError(msg);
}

std::vector<std::string> GlContext::take_messages() {
  std::lock_guard<std::mutex> lock(impl_->m);
  std::vector<std::string> out;
  out.swap(impl_->messages);
  return out;
}

}  // namespace bloomref::gpu
