// Stage images from outside bloomref (a user's dumps, a RenderDoc capture): how each file is
// declared (encoding, row order, channel order, raw layout), found in a folder by stage name,
// and loaded into a top-row-first RGBA float image. Every problem is an InputError naming the
// file and the field (exit 2).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "bloomref/image.h"
#include "bloomref/plan.h"

namespace bloomref::cli {

/// exr: OpenEXR half or float. png-linear: the PNG's codes / 255 are the stage's values (what
/// `run -o out.png` writes of `output`). png-srgb: the codes are sRGB-encoded values (an
/// SRGB8_ALPHA8 target), decoded with the sRGB curve. raw: headerless float or half values, as
/// RenderDoc's "Save Texture" with the Raw format writes them. auto: by extension (.exr, .png
/// as png-linear, .raw / .bin as raw; other extensions through OpenImageIO as float).
enum class Encoding { automatic, exr, png_linear, png_srgb, raw };
enum class Origin { top, bottom };
enum class ChannelOrder { rgba, bgra, rgb };
enum class RawFormat { f32, f16 };

Encoding parse_encoding(const std::string& s);
Origin parse_origin(const std::string& s);
ChannelOrder parse_channel_order(const std::string& s);
RawFormat parse_raw_format(const std::string& s);
std::string to_string(Encoding e);
std::string to_string(Origin o);
std::string to_string(ChannelOrder c);

/// How one file holds its stage.
struct StageFile {
  std::string stage;  ///< the stage name (input, bright, blur.k, ..., output)
  std::string path;
  Encoding encoding = Encoding::automatic;
  Origin origin = Origin::top;
  ChannelOrder channels = ChannelOrder::rgba;
  RawFormat format = RawFormat::f32;  ///< raw only
  int width = 0, height = 0;          ///< raw only; 0: the stage's size in the plan
  /// In memory (the Python module's arrays): the image itself, `path` the caller's name for it.
  const ConstImageView* image = nullptr;
};

struct LoadedStage {
  Image image;
  int code_bits = 0;  ///< 8 for PNG captures
  bool srgb = false;
};

/// Reads one stage file; `width` x `height` is the size the stage has in this plan (a raw file
/// without a declared size takes it). InputError naming the file for an unreadable or corrupt
/// file, a raw file of the wrong byte count, or an image of another size than the stage's.
LoadedStage load_stage(const StageFile& f, int width, int height);

/// Whether `name` has the form of a stage name (input, bright, blur.N, down.N, up.N, bloom,
/// composite, tonemap, output), whether or not this plan has it.
bool looks_like_stage(const std::string& name);

/// The stage images of a folder: files named <stage>.<ext> (ext exr, png, raw, bin, hdr, tif,
/// tiff), or <alias>.<ext> for an alias of `aliases` (a user's name -> a stage name), each with
/// the defaults of `proto` (encoding, origin, channels, raw format). Files whose name is not a
/// stage's are listed in `ignored`. InputError (naming the file) for a
/// stage-like name this plan lacks (blur.99 beyond --passes, down.k with --method gaussian),
/// and for two files of one stage; for a folder that does not exist.
std::vector<StageFile> find_stage_files(const std::string& dir, const Plan& plan,
                                        const StageFile& proto,
                                        const std::map<std::string, std::string>& aliases,
                                        std::vector<std::string>& ignored);

/// InputError naming the file when `f.stage` is not a stage of `plan`.
void require_stage_in_plan(const StageFile& f, const Plan& plan);

/// The size stage `name` has in `plan` (full size, or its mip level's).
void stage_size(const Plan& plan, const std::string& name, int& width, int& height);

}  // namespace bloomref::cli
