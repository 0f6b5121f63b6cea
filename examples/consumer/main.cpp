// Runs a bloom through the installed library and checks it against values computed here.
//
// The scene is 64x32 at 0.25 (below the threshold of 1) with one pixel of 8 at (48, 24). Ten
// passes of the 9-tap kernel reach 5 x 4 = 20 texels along each axis, so at (0, 0) the bloom is
// exactly 0 and the output is the tone map and gamma of 0.25 alone:
// pow(1 - exp(-0.25), 1 / 2.2) (docs/design.md, "Specification", stages 5 and 6). Next to the bright pixel the bloom
// adds light. With a path argument, the output is written there as EXR and read back.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>

#include "bloomref/error.h"
#include "bloomref/executor.h"
#include "bloomref/io.h"

int main(int argc, char** argv) {
  try {
    bloomref::Image scene(64, 32, 0.25f);
    for (int c = 0; c < 3; ++c) scene.pixel(48, 24)[c] = 8.0f;
    for (int y = 0; y < scene.height(); ++y)
      for (int x = 0; x < scene.width(); ++x) scene.pixel(x, y)[3] = 1.0f;

    const bloomref::BloomParams params;  // the seeds' defaults
    const bloomref::Plan plan = bloomref::make_plan(params, scene.cview(), "consumer scene");
    const bloomref::StageTrace trace = bloomref::execute(plan, scene.cview());
    const bloomref::Image& out = trace.final_image();

    int failures = 0;
    const double expected = std::pow(1.0 - std::exp(-0.25), 1.0 / 2.2);
    const double corner = out.pixel(0, 0)[0];
    // The oracle computes in float: a few float ULPs (2^-24 relative each) from the double value.
    if (std::fabs(corner - expected) > 8 * std::ldexp(expected, -24)) {
      std::fprintf(stderr, "output at (0, 0) is %.9g, expected %.9g\n", corner, expected);
      ++failures;
    }
    const double beside = out.pixel(47, 24)[0];
    if (!(beside > corner)) {
      std::fprintf(stderr, "output beside the bright pixel is %.9g, not above %.9g\n", beside, corner);
      ++failures;
    }
    if (argc > 1) {
      bloomref::save_exr(argv[1], out.cview());
      const bloomref::LoadedImage back = bloomref::load_image(argv[1]);
      if (back.image.values().size() != out.values().size() ||
          std::memcmp(back.image.data(), out.data(), out.values().size() * sizeof(float)) != 0) {
        std::fprintf(stderr, "%s does not read back with the same bits\n", argv[1]);
        ++failures;
      }
    }
    std::printf("bloomref consumer: output (0, 0) = %.9g (expected %.9g), beside the light %.9g: %s\n",
                corner, expected, beside, failures ? "FAIL" : "ok");
    return failures ? 1 : 0;
  } catch (const bloomref::Error& e) {
    std::fprintf(stderr, "bloomref consumer: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bloomref consumer: internal error: %s\n", e.what());
    return 4;
  }
}
