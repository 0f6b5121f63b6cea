"""bloomref vulkan-info: the Vulkan device, its reported limits, and the facts a compute probe
measures on it (vulkan/src/device_facts.cpp).

Skips without a Vulkan device (exit 3) unless BLOOMREF_REQUIRE_VULKAN=1 (CI: lavapipe is always
installable). On Mesa's software devices the facts are checked against an independent
measurement: gl-info's GL probe on llvmpipe, which shares the Vulkan driver's sampler and
store code (gallivm), must find the same store rounding and filter precision.
"""
import json
import os
import subprocess

import pytest

from cli_support import EXE, run


def vulkan_or_skip(code, err):
    if code == 3:
        if os.environ.get("BLOOMREF_REQUIRE_VULKAN") == "1":
            pytest.fail("no Vulkan although BLOOMREF_REQUIRE_VULKAN=1: " + err)
        pytest.skip("no Vulkan: " + err.strip())


@pytest.fixture(scope="module")
def info(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("vulkan")
    code, out, err = run(["vulkan-info", "--json", "v.json"], tmp)
    vulkan_or_skip(code, err)
    assert code == 0, err
    j = json.loads((tmp / "v.json").read_text())
    assert json.loads(out) == j  # the console and the file say the same
    return j


def test_reports_the_limits_the_precision_model_needs(info):
    r = info["reported"]
    assert info["api"] == "vulkan" and info["device"] and info["api_version"].count(".") == 2
    # Vulkan 1.x requires at least 4 sub-texel bits and 4 mipmap bits (the spec's limit table).
    assert r["sub_texel_precision_bits"] >= 4 and r["mipmap_precision_bits"] >= 4
    assert r["max_workgroup_invocations"] >= 128 and min(r["max_workgroup_size"]) >= 64
    assert r["timestamp_period_ns"] > 0
    assert set(r["float_controls"]) >= {"denorm_behavior_independence", "rounding_rte_f32"}


def test_measured_facts_are_consistent(info):
    m = info["measured"]
    assert m["half_rounding"] in ("nearest-even", "toward-zero", "other")
    distinct, bits = m["bilinear_distinct_of_1024"], m["subtexel_bits"]
    assert 2 <= distinct <= 1024
    if bits:  # b-bit fixed-point weights give 2^b or 2^b + 1 values across one span
        assert distinct in (1 << bits, (1 << bits) + 1)
    else:
        assert distinct >= 1000
    # A toward-zero store saturates 65520 to the largest half; a nearest one does not go below it.
    if m["half_rounding"] == "toward-zero":
        assert m["half_of_65520"] == 65504.0


def test_a_device_that_is_not_there_exits_3(tmp_path):
    """BLOOMREF_VULKAN_DEVICE names a device no machine has: exit 3, the variable named."""
    p = subprocess.run([EXE, "vulkan-info"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, env={**os.environ, "BLOOMREF_VULKAN_DEVICE": "no-such-device-42"})
    assert p.returncode == 3, p.stderr
    assert "BLOOMREF_VULKAN_DEVICE" in p.stderr and "no-such-device-42" in p.stderr, p.stderr


def test_lavapipe_agrees_with_llvmpipe_gl(info, tmp_path):
    """Mesa's two software drivers share the sampler and store code: the Vulkan probe must find
    what the GL probe finds (store rounding, saturation, weight precision, FMA)."""
    if "llvmpipe" not in info["device"]:
        pytest.skip("not Mesa's software Vulkan device: " + info["device"])
    code, _, err = run(["gl-info", "--json", "g.json"], tmp_path)
    if code == 3:
        pytest.skip("no GL to compare with: " + err.strip())
    gl = json.loads((tmp_path / "g.json").read_text())
    if "llvmpipe" not in gl["renderer"]:
        pytest.skip("GL is not llvmpipe: " + gl["renderer"])
    m = info["measured"]
    for key in ("half_rounding", "half_of_65520", "half_of_70000", "half_denormals_kept",
                "f32_denormals_kept", "bilinear_distinct_of_1024", "subtexel_bits",
                "fma_contracted"):
        assert m[key] == gl[key], (key, m[key], gl[key])
