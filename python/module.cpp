// The Python module `bloomref`: bloom on numpy arrays with the command line's options and bits,
// and the check of anyone's stage images. Errors: bad input or options raise ValueError with the
// reason; no GL device for backend='gl' or shaders= raises bloomref.GlUnavailable (a
// RuntimeError); anything else RuntimeError.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "app.h"
#include "bloomref/error.h"
#include "bloomref/image.h"
#include "bloomref/gpu/context.h"
#include "check.h"
#include "files.h"
#include "run.h"

namespace py = pybind11;

namespace {

constexpr const char* kRunDoc = R"(run(image=None, *, keep_stages=False, out=None, **options)

Applies bloom as `bloomref run` does, with the same bits.

image: a numpy array of H x W x 4 (RGBA) or H x W x 3 (RGB, alpha 1) floats, linear and
    scene-referred, row 0 on top; a float32 H x W x 4 array whose pixels are contiguous (C order,
    or a crop of one) is read in place, any other is converted first. Or an image path (EXR,
    .hdr, PNG, TIFF...), or None for the built-in scene (options scene, size).
keep_stages: return every stage instead of the output.
out: an array to write the output into (float32, H x W x 4, C order, writeable), returned.
    `out=image` runs in place, overwriting the scene as the command does with the image it
    loads: the fastest form for an array this module returned (bloomref.load, an earlier
    output), whose buffer the run then uses directly; any other array receives a copy.
options: `bloomref run`'s options, named as its long options with underscores: method,
    threshold, exposure, gamma, passes, kernel, strength, storage, precision, nonfinite,
    subtexel_bits, threads, plan, blur, levels, karis, composite, scene, size, backend,
    gl_shaders. Their defaults and checks are the command's (bloomref run --help).

Returns the output, a float32 H x W x 4 array (display-referred: after tone map and gamma; out
when given), or with keep_stages a dict from stage name (input, bright, blur.1 ... output) to
its array, in pipeline order. The arrays own their buffers (no copy). The computation runs
without the GIL.
Raises ValueError for a bad image or option (the reason in the message).)";

constexpr const char* kCheckDoc = R"(check(scene=None, stages=None, **options)

Judges captured bloom stages against the oracle, as `bloomref check` does.

scene: the HDR image the stages were rendered from: an array (as for run), an image path, or
    None for the built-in scene (options scene, size).
stages: a folder of stage images named as --dump-stages names them, or a dict from stage name
    (bright, blur.1 ... output) to an array or an image path; None with the manifest or shaders
    option.
options: `bloomref check`'s options, named as its long options with underscores: the pipeline
    options of run, profile, encoding, origin, channels, raw_format, expectations, no_causes,
    warn_as_error, device_api, device_vendor, device_renderer, device_driver, manifest,
    shaders, blur_fs, final_fs, ..., and json, junit, markdown, report to write those files too.

Returns the result as `check --json` writes it (docs/schemas/check-result.v1.json): verdict,
exit_code, items with their stages' verdicts, errors, bounds and likely causes. Arrays are
read in memory, nothing written for them, and named by their key in the result
(stages['blur.3']). Raises ValueError for bad input or options, and when no stage was compared.)";

constexpr const char* kLoadDoc = R"(load(path)

Reads an image file as bloomref run does (EXR through OpenEXR, other formats through
OpenImageIO): a float32 H x W x 4 array, RGB files with alpha 1. Raises ValueError naming the
file and the problem.)";

constexpr const char* kSaveDoc = R"(save(path, image)

Writes an array (as run takes it) as bloomref run writes its output: .exr holds 32-bit float
RGBA, .png 8-bit RGB quantised as round(clamp(x, 0, 1) * 255); written to a temporary file and
renamed into place.)";

constexpr const char* kCommandDoc = R"(run_command_line(args)

Runs a bloomref command line in this process (the arguments after the program name, e.g.
["run", "in.exr", "-o", "out.exr"]) and returns its exit code (0 success, 1 FAIL, 2 bad usage
or input, 3 GL unavailable, 4 internal error, 5 nothing compared). It prints as the command does.)";

}  // namespace

PYBIND11_MODULE(bloomref, m) {
  // Large buffers as numpy's own: advised for huge pages. A Python process runs image after
  // image of one size and keeps the buffers (arrays.cpp, kept_buffer; the scratch pool), so
  // the slower first touch is paid once (docs/design.md, "Large buffers advised for huge pages in the Python
  // process", has the figures).
  bloomref::advise_huge_pages(true);
  m.doc() = "bloomref: the reference HDR bloom (CPU oracle, GL parity, check) on numpy arrays";
  m.attr("__version__") = BLOOMREF_VERSION;
  static py::exception<bloomref::gpu::GlUnavailable> gl_unavailable(m, "GlUnavailable",
                                                                    PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const bloomref::gpu::GlUnavailable& e) {
      PyErr_SetString(gl_unavailable.ptr(), e.what());
    } catch (const bloomref::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bloomref::ParamError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bloomref::Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
  m.def("run", &bloomref::python::run, kRunDoc, py::arg("image") = py::none(), py::kw_only(),
        py::arg("keep_stages") = false, py::arg("out") = py::none());
  m.def("check", &bloomref::python::check, kCheckDoc, py::arg("scene") = py::none(),
        py::arg("stages") = py::none());
  m.def("load", &bloomref::python::load, kLoadDoc, py::arg("path"));
  m.def("save", &bloomref::python::save, kSaveDoc, py::arg("path"), py::arg("image"));
  m.def(
      "run_command_line",
      [](const std::vector<std::string>& args) {
        py::gil_scoped_release unlocked;
        return bloomref::cli::run_command_line(args);
      },
      kCommandDoc, py::arg("args"));
}
