"""check --shaders pipeline --backend vulkan with users' compute shaders (docs/check.md, "Compute
shaders"): GLSL, HLSL and SPIR-V bound by their reflected bindings to a description's textures.

data/pipelines/compute-chain.json is GraphicsSandbox's host layout (a public compute-shader
bloom: Itachi546/GraphicsSandbox, BloomPass.cpp) around bloomref's compute shaders of its
interface. They pass; copies with the bugs that project's own shaders ship, planted one at a
time, fail at the stage where each enters; descriptions that do not match the shaders'
bindings are refused naming the file and the binding.
Skips without Vulkan (exit 3) unless BLOOMREF_REQUIRE_VULKAN=1.
"""
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from cli_support import run

ROOT = Path(__file__).resolve().parents[2]
PIPELINES = ROOT / "data" / "pipelines"
CHAIN = PIPELINES / "compute-chain"
# The chain the shaders compute: the bright image (luminance > 1) down five levels with the 13-tap
# filter, no Karis average, and back up with the tent, stored in f16.
PARAMS = ["--method", "mip", "--prefilter", "bright", "--levels", "5", "--storage", "f16"]
SIZE = "256x192"  # every level exactly half the one above: radius 2 is one texel of the smaller


def vulkan_or_skip(code, err):
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())


def description(tmp_path, edit=None, **shaders):
    """compute-chain.json with absolute paths; `shaders` maps a program to a replacement file."""
    d = json.loads((PIPELINES / "compute-chain.json").read_text())
    for name, prog in d["programs"].items():
        prog["compute"] = str(shaders.get(name, PIPELINES / prog["compute"]))
    if edit:
        edit(d)
    f = tmp_path / "chain.json"
    f.write_text(json.dumps(d))
    return f


def check(tmp_path, f, *options, params=PARAMS):
    code, out, err = run(["check", "--scene", "demo", "--size", SIZE, *params, "--shaders",
                          "pipeline", "--pipeline", str(f), "--backend", "vulkan", *options,
                          "--json", "c.json", "-q"], tmp_path, timeout=600)
    vulkan_or_skip(code, err)
    return code, err, (json.loads((tmp_path / "c.json").read_text())["items"][0]
                       if code in (0, 1) else None)


def broken(tmp_path, name, find, replace):
    text = (CHAIN / name).read_text()
    assert find in text, find
    f = tmp_path / name
    f.write_text(text.replace(find, replace))
    return f


def test_the_chain_passes_in_glsl(tmp_path):
    code, err, item = check(tmp_path, description(tmp_path))
    assert code == 0 and item["verdict"] == "PASS", err
    assert [s["stage"] for s in item["stages"]] == [
        "down.1", "down.2", "down.3", "down.4", "down.5", "up.4", "up.3", "up.2", "up.1"]


def test_the_downsample_passes_as_spirv(tmp_path):
    spv = tmp_path / "downsample.spv"
    subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", "-o", str(spv),
                    str(CHAIN / "downsample.comp")], check=True, capture_output=True)
    code, err, item = check(tmp_path, description(tmp_path, down=spv))
    assert code == 0 and item["verdict"] == "PASS", err


def test_the_downsample_passes_in_hlsl(tmp_path):
    """HLSL's texture and sampler are apart (both bound to the level read); its RWTexture2D is
    rgba32f, so the chain is judged in f32, the downsamples alone."""
    def edit(d):
        d["programs"]["down"]["compute"] = str(CHAIN / "downsample.hlsl")
        d["textures"][0]["format"] = "rgba32f"
        d["textures"][1]["textures"][0]["format"] = "rgba32f"
        d["passes"][0]["inputs"]["uSampler"] = "bright"
        d["passes"][1]["passes"][0]["inputs"]["uSampler"] = "mip{k-1}"
        d["passes"] = d["passes"][:2]
    params = PARAMS[:-1] + ["f32"]
    code, err, item = check(tmp_path, description(tmp_path, edit), params=params)
    assert code == 0 and item["verdict"] == "PASS", err
    assert len(item["stages"]) == 5
    # An f16 bright image where the pipeline judged is f32: seen at down.1.
    def f16_bright(d):
        edit(d)
        d["textures"][0]["format"] = "rgba16f"
    code, err, item = check(tmp_path, description(tmp_path, f16_bright), params=params)
    assert item["verdict"] in ("WARN", "FAIL") and item["first_divergent_stage"] == "down.1", err


def test_constants_from_a_uniform_buffer(tmp_path):
    """The upsample's constants in a uniform buffer (std140, binding 2) instead of push
    constants: set by member name the same way."""
    ubo = broken(tmp_path, "upsample.comp", "layout(push_constant) uniform PushConstant {",
                 "layout(binding = 2) uniform Params {")
    code, err, item = check(tmp_path, description(tmp_path, up=ubo))
    assert code == 0 and item["verdict"] == "PASS", err
    # the radius in the buffer doubled: the tent's taps two texels apart fail at up.4
    def wide(d):
        d["passes"][2]["passes"][0]["uniforms"]["radius"] = 4.0
    code, err, item = check(tmp_path, description(tmp_path, wide, up=ubo))
    assert code == 1 and item["first_divergent_stage"] == "up.4", err


# The bugs GraphicsSandbox's own shaders ship (downsample.comp.glsl, upsample.comp.glsl at
# fddfdcf), planted one at a time into the correct copies.
BUGS = [
    ("downsample.comp", "(vec2(texel) + 0.5) / vec2(width, height)",
     "vec2(texel) / vec2(width, height)", "down.1"),           # the texel's corner, not its centre
    ("downsample.comp", "1.0 / vec2(textureSize(uInputTexture, 0))",
     "1.0 / vec2(width, height)", "down.1"),                   # steps of the target's texel
    ("downsample.comp", "imageStore(uOutputTexture, texel, vec4(sum, 1.0));",
     "imageStore(uOutputTexture, texel, vec4(max(sum, 0.0001), 1.0));", "down.1"),  # a floor
    ("upsample.comp", "level + tent * (1.0 / 16.0)",
     "(level + tent) * (1.0 / 16.0)", "up.4"),                 # the level scaled with the tent
    ("upsample.comp", "(vec2(texel) + 0.5) / vec2(width, height)",
     "vec2(texel) / vec2(width, height)", "up.4"),
]


@pytest.mark.parametrize("name,find,replace,stage", BUGS,
                         ids=["down-corner", "down-target-step", "down-floor", "up-level-scaled",
                              "up-corner"])
def test_graphicssandboxs_bugs_fail_where_they_enter(tmp_path, name, find, replace, stage):
    program = "down" if name.startswith("down") else "up"
    f = description(tmp_path, **{program: broken(tmp_path, name, find, replace)})
    code, err, item = check(tmp_path, f)
    assert code == 1 and item["verdict"] == "FAIL", err
    assert item["first_divergent_stage"] == stage, item["first_divergent_stage"]


@pytest.mark.parametrize("edit,words", [
    # a storage image the shader does not have
    (lambda d: d["passes"][0]["images"].update(uOut="mip0"), "'uOut', which is not a storage image"),
    # the shader's storage image given no texture
    (lambda d: d["passes"][0].update(images={}), "'uOutputTexture' (binding 1, a storage image)"),
    # a texture whose format is not the one the shader declares
    (lambda d: d["textures"][1]["textures"][0].update(format="r11f_g11f_b10f"), "declared rgba16f"),
    # a push constant misspelt
    (lambda d: d["passes"][0]["uniforms"].update(widht=1.0), "'widht', which is not a push constant"),
    # a push constant not set
    (lambda d: d["passes"][0]["uniforms"].pop("height"), "does not set 'height' (float)"),
    # a binding by number that is not a storage image
    (lambda d: d["passes"][0]["images"].update({"0": "mip0"}), "'0', which is not a storage image"),
])
def test_descriptions_that_do_not_match_the_bindings_are_refused(tmp_path, edit, words):
    f = description(tmp_path, edit)
    code, err, _ = check(tmp_path, f)
    assert code == 2 and words in err and "downsample.comp" in err and str(f) in err, err


def test_shaders_bloomref_cannot_bind_are_refused_naming_the_file(tmp_path):
    # one that does not compile: the compiler's message
    f = description(tmp_path, down=broken(tmp_path, "downsample.comp", "vec3 sum =", "vec3 sum = nope +"))
    code, err, _ = check(tmp_path, f)
    assert code == 2 and "downsample.comp" in err and "nope" in err, err
    # one in descriptor set 1
    f = description(tmp_path, down=broken(tmp_path, "downsample.comp", "layout(binding = 0)",
                                          "layout(set = 1, binding = 0)"))
    code, err, _ = check(tmp_path, f)
    assert code == 2 and "descriptor set 1" in err and "downsample.comp" in err, err
    # a file that is not SPIR-V
    bad = tmp_path / "not.spv"
    bad.write_bytes(b"\x01\x02\x03\x04" * 8)
    code, err, _ = check(tmp_path, description(tmp_path, down=bad))
    assert code == 2 and "not.spv" in err and "not SPIR-V" in err, err


def test_a_compute_program_is_refused_on_gl(tmp_path):
    code, _, err = run(["check", "--scene", "demo", "--size", SIZE, *PARAMS, "--shaders",
                        "pipeline", "--pipeline", str(description(tmp_path))], tmp_path)
    assert code in (2, 3), err
    if code == 2:
        assert "compute shader" in err and "--backend vulkan" in err, err
