"""The classical WV kernels' bits are frozen: the sums of every level, for signals built from
integer arithmetic only (the same numbers on any platform and NumPy version), must equal values
stored here, which the kernel gave when the paper studies' results were computed. A speed change
to gmwm/_haar.c or gmwm/_wvkernels.py that moves one bit of one level fails here (the studies
would then have to be rerun). Checked: the C kernel on 1, 2 and 3 threads (the thread split
decides which blocks start from a recomputed halo and which continue the previous block), its
baseline build without the AVX2 clones, the Numba twin, and wvar on float32 input and on a drift.
"""

from __future__ import annotations

import os
import subprocess
import sysconfig
import types
from importlib.machinery import ExtensionFileLoader
from importlib.util import module_from_spec, spec_from_file_location
from pathlib import Path

import numpy as np
import pytest

from conftest import needs_c_kernel
from gmwm.wv import Workspace, wvar

SRC = Path(__file__).resolve().parents[1] / "src" / "gmwm" / "_haar.c"


def splitmix_uniform(n: int, seed: int) -> np.ndarray:
    """``n`` uniforms in [0, 1) (53 bits) from SplitMix64 of a counter: unsigned 64-bit integer
    arithmetic (wrapping), then an exact conversion, so no generator version is involved."""
    golden = np.uint64(0x9E3779B97F4A7C15)
    with np.errstate(over="ignore"):
        z = np.arange(1, n + 1, dtype=np.uint64) + np.uint64(seed) * golden
        z = z * golden
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def signal(T: int, kind: str, seed: int) -> np.ndarray:
    """White noise on a 1e8 offset (``wn``), a random walk on a 1e8 offset plus small white noise
    (``rw``), or a drift plus a random walk and white noise (``drift``); ``np.cumsum`` adds in
    order, so these are exact functions of the uniforms."""
    u = splitmix_uniform(T, seed) - 0.5
    e = splitmix_uniform(T, seed + 1000) - 0.5
    if kind == "wn":
        return 1e8 + u
    if kind == "rw":
        return 1e8 + np.cumsum(u) + 1e-3 * e
    return 3.0 + 1e-4 * np.arange(T) + np.cumsum(u) * 1e-2 + e


#: (T, J, layout (L, block, panel) or None for the default, kind) -> the J sums
#: sum_t (2 W_{j,t})**2 as float.hex; signal i of the list has seed i. Tiny and odd lengths, J from
#: 1 to the maximum, phase 1 only, one phase-2 level, odd and even L up to 13, blocks shorter
#: than 2**L, equal to it and not a multiple of it, panels of 1 to 16 sub-series.
FROZEN = {
    (4, 1, None, "wn"):
        "0x1.429be8afbe836p+0",
    (5, 1, None, "rw"):
        "0x1.1908de4b6d160p-2",
    (7, 1, None, "drift"):
        "0x1.b44e3f5bd57d9p-1",
    (33, 4, None, "rw"):
        "0x1.6930cc5d5eeacp+1 0x1.34a778bea564cp+2 0x1.9586ba1f98ee8p+2 "
        "0x1.ab6598de6a40fp+2",
    (100, 5, None, "wn"):
        "0x1.18b626442e964p+4 0x1.faa27f75b915ap+2 0x1.154a1286f76afp+1 "
        "0x1.37b8999e4ff1dp+0 0x1.9f6db068f95eap-1",
    (1000, 8, None, "rw"):
        "0x1.4a0a0cb5a8208p+6 0x1.04f36641cc957p+7 0x1.b5482857f354dp+7 "
        "0x1.824d658b402bep+8 0x1.5cc1323a3d39dp+9 0x1.66fc77c7c2dfbp+10 "
        "0x1.acde2d4dfd9f6p+11 0x1.27b3b144d3ddcp+13",
    (4097, 11, None, "drift"):
        "0x1.4f46abe1723f6p+9 0x1.45dc5698ac953p+8 0x1.4b98435b3fa17p+7 "
        "0x1.430879c791207p+6 0x1.2f3f313526239p+5 0x1.3ec4e55821414p+4 "
        "0x1.988d5442eec04p+3 0x1.ad0726a531217p+2 0x1.40017d3c1952cp+2 "
        "0x1.e14b8477ea514p+1 0x1.dd3f46f2a3684p+0",
    (65537, 15, None, "rw"):
        "0x1.543932f58f49bp+12 0x1.ff7f0c35b79fap+12 0x1.d6b414e8e9122p+13 "
        "0x1.c98662f7767d2p+14 0x1.bfe37221ecaa4p+15 0x1.bb0213b278c6bp+16 "
        "0x1.b49849389c284p+17 0x1.b1aa410d4ee65p+18 0x1.bc9d77cfae484p+19 "
        "0x1.b25b056632336p+20 0x1.7b62da4d3f5e3p+21 0x1.519a9a864d8eap+22 "
        "0x1.2cd356ffca037p+23 0x1.20e9e1d9e3265p+24 0x1.7f9d4b84c56edp+24",
    (300007, 17, None, "rw"):
        "0x1.8638b2eda8481p+14 0x1.23ec3f2b363cap+15 0x1.0aa430b581271p+16 "
        "0x1.0550f42f5fc71p+17 0x1.0769900d3ba7fp+18 0x1.08806bdf228f9p+19 "
        "0x1.038b2928fcf0fp+20 0x1.fa3ab702d19b2p+20 0x1.ebbd0a8a89cb4p+21 "
        "0x1.e2a5e7755a8abp+22 0x1.e94fcad5d0d01p+23 0x1.018e081fa6bf6p+25 "
        "0x1.1818e0687ef62p+26 0x1.027f55ea15051p+27 0x1.fd4373b77ae6bp+27 "
        "0x1.79121a2ce37a2p+28 0x1.2b5f5d096f7e8p+28",
    (300007, 17, None, "wn"):
        "0x1.854cf57b507a8p+15 0x1.869b30492de32p+14 0x1.883ae76d5b369p+13 "
        "0x1.85eea5b7a3b8fp+12 0x1.86697c9a4d841p+11 0x1.8a8e29f143464p+10 "
        "0x1.81d8040ddaa5fp+9 0x1.78eee503e50c9p+8 0x1.830804d6ccd65p+7 "
        "0x1.8c8b3f356f50ep+6 0x1.9159220ab775ap+5 0x1.aecc57f3cf836p+4 "
        "0x1.63d86126f28f1p+3 0x1.68df25a42b5ddp+2 0x1.5ada3b2bcf1f6p+1 "
        "0x1.c5c9b878e9eb9p+0 0x1.17c8b482c4586p+0",
    (300007, 12, None, "drift"):
        "0x1.8824209975e02p+15 0x1.85c8ff527b54ep+14 0x1.8639a75c29868p+13 "
        "0x1.8a4534043ccfdp+12 0x1.8ee045e8812edp+11 0x1.93d4a5bfbd9d4p+10 "
        "0x1.b31609d5c66bcp+9 0x1.3973534f615f9p+9 0x1.80fa9e82c75c6p+9 "
        "0x1.883982d2525bdp+10 0x1.07f83d12f5bcbp+12 0x1.a7e61e3f6acf3p+13",
    (300007, 11, None, "rw"):
        "0x1.872aba2922e37p+14 0x1.245116dd799a3p+15 0x1.0ac6c07daee84p+16 "
        "0x1.0370bbcb5d79ep+17 0x1.02fa88cf4e0f0p+18 0x1.042c4b6dec801p+19 "
        "0x1.0717bd9a1a52cp+20 0x1.0d6a344aef895p+21 0x1.10e10f58dd877p+22 "
        "0x1.0e6584b8fbba2p+23 0x1.fe878ba3e008ap+23",
    (300007, 17, (12, 16384, 8), "rw"):
        "0x1.86738e736e5e0p+14 0x1.263a8d4ad1bbdp+15 0x1.0dc364cbb78d4p+16 "
        "0x1.07963da1200fcp+17 0x1.0584420dcf897p+18 0x1.02b4b44cddd40p+19 "
        "0x1.febcaf6dad70dp+19 0x1.02733995b07f4p+21 0x1.00febfb1bfc5bp+22 "
        "0x1.f841e6982091dp+22 0x1.f7ee6bd9dbe9fp+23 0x1.04bddc3e39b36p+25 "
        "0x1.094b2eb06ee93p+26 0x1.db558280f1b35p+26 0x1.a4d3fb12d0c9bp+27 "
        "0x1.cb5b0512ce598p+27 0x1.5a877920db32ap+28",
    (200003, 16, (10, 3000, 5), "drift"):
        "0x1.0384a53291a48p+15 0x1.024e11104a325p+14 0x1.04449c9d52f78p+13 "
        "0x1.0414384ca5195p+12 0x1.06d425becc8f2p+11 0x1.0b84c11ecb1bep+10 "
        "0x1.25782a71ca9e9p+9 0x1.9fb80fd21d408p+8 0x1.0cb98d873e7c1p+9 "
        "0x1.256183a407251p+10 0x1.98fffe60352d1p+11 0x1.432908665fb9ap+13 "
        "0x1.1559f9985c650p+15 0x1.e6c0a5f77fdccp+16 0x1.a54ef29c1572bp+18 "
        "0x1.53a473e1e850cp+20",
    (100003, 16, (6, 40, 3), "rw"):
        "0x1.053563dae127ep+13 0x1.88fd89f5b858bp+13 0x1.6c284065409ccp+14 "
        "0x1.634548de75b63p+15 0x1.5f2b084b6a9ffp+16 0x1.5e651f7fc3547p+17 "
        "0x1.5dc4062a8d17bp+18 0x1.63640141a4a77p+19 0x1.720f633a2720bp+20 "
        "0x1.9cc924ddce6afp+21 0x1.d846240c876e2p+22 0x1.ecaa4c043f5f3p+23 "
        "0x1.afcbe035ce1c5p+24 0x1.c0c8ec4bc81cap+25 0x1.b7e7a2125c6ddp+26 "
        "0x1.03dfd13cf63b2p+27",
    (150001, 16, (7, 128, 16), "wn"):
        "0x1.88aa047e67a69p+14 0x1.857db9d7a480fp+13 0x1.8a239033477d8p+12 "
        "0x1.86817376a3d5fp+11 0x1.88ff2bf94a740p+10 0x1.8303960ac8220p+9 "
        "0x1.8e4a210ca67ebp+8 0x1.95f94ee46a4e1p+7 0x1.8c1d8f8f6837ep+6 "
        "0x1.9cefc82e55a64p+5 0x1.68e0454f1bd3cp+4 0x1.9e4c5a500507dp+3 "
        "0x1.a0f3849352c74p+2 0x1.a69a8d3a8ccbdp+1 0x1.57461630bef65p+0 "
        "0x1.139fc8a7a9abep-2",
    (123457, 15, (3, 64, 1), "rw"):
        "0x1.408db2c040120p+13 0x1.e1e5e7e5f38f5p+13 0x1.b94c9a005a9a7p+14 "
        "0x1.b0114a33cf220p+15 0x1.aaf9f7bd05146p+16 0x1.a44cfb0fc610dp+17 "
        "0x1.9dde2dbc302cep+18 0x1.90030db519800p+19 0x1.8e014c96ff72ep+20 "
        "0x1.9f1d458d76d7dp+21 0x1.af2be1f10d8dcp+22 0x1.bf6ee96585473p+23 "
        "0x1.575be3261f774p+24 0x1.184f0511c0f92p+25 0x1.63527fe7bdfd6p+25",
    (131071, 15, (1, 16, 2), "drift"):
        "0x1.5525aa04afc3ap+14 0x1.5447d9fe76ad0p+13 0x1.56cfe4e75cd64p+12 "
        "0x1.5398bde01e4b5p+11 0x1.5235ad17d17c7p+10 0x1.5e23e07a9e5d5p+9 "
        "0x1.86c00f47da994p+8 0x1.206efa4c65210p+8 0x1.5cc0bf429133ep+8 "
        "0x1.5b461b82cbafep+9 0x1.e77f39a75e343p+10 0x1.93ed01779b562p+12 "
        "0x1.63d0008fe3cb6p+14 0x1.4148fa8d9e4f6p+16 0x1.16b7c87e56c04p+18",
    (262147, 17, (9, 4096, 8), "rw"):
        "0x1.54fcae523c7d8p+14 0x1.0038bf089c988p+15 0x1.d791c4d8089dbp+15 "
        "0x1.cd02aa7daf006p+16 0x1.c9c902e8b12dbp+17 0x1.c5c2a7c23c8bdp+18 "
        "0x1.be4608d5c500ap+19 0x1.ade749c21f16ap+20 0x1.9a84e80db433fp+21 "
        "0x1.8aed766036c91p+22 0x1.786e068cbeb68p+23 0x1.8916fb76c61b1p+24 "
        "0x1.a9f87543ec9c1p+25 0x1.b913ae78e26c6p+26 0x1.b1b92a534d559p+27 "
        "0x1.12731a333688bp+29 0x1.67f02d28df3d9p+29",
    (300007, 17, (13, 65536, 8), "rw"):
        "0x1.8636610915651p+14 0x1.2454eedc998aap+15 0x1.0b07323e1aba0p+16 "
        "0x1.041d554530acfp+17 0x1.006aad38f0bfap+18 0x1.f9a405b6499dap+18 "
        "0x1.f7e147aaecdfap+19 0x1.f9a9ad4e82ecdp+20 0x1.04b5af78e5653p+22 "
        "0x1.0c615eba33cfep+23 0x1.0e1cfab9e9a94p+24 0x1.fea67b441c7a4p+24 "
        "0x1.c0a8755d813b6p+25 0x1.70254f58f90c3p+26 0x1.50748cea12b19p+27 "
        "0x1.67fb6ade7613fp+28 0x1.15949641a0da8p+29",
    (345679, 17, (13, 24581, 8), "drift"):
        "0x1.c1e8332785bc6p+15 0x1.c2f8c7949f7d9p+14 0x1.c2a035123c09fp+13 "
        "0x1.c56cae5993ffep+12 0x1.c7d133b0088e6p+11 0x1.cc84d3e4d137fp+10 "
        "0x1.0093ace0ce24fp+10 0x1.7704d358da03bp+9 0x1.cc52daa5235fcp+9 "
        "0x1.d4674734f60dfp+10 0x1.43010daa3696ep+12 0x1.01a181bdf2193p+14 "
        "0x1.b88d09717629dp+15 0x1.88d5992781a25p+17 0x1.62df779e1a103p+19 "
        "0x1.405a41db8c0f8p+21 0x1.f80d25f80e3aap+22",
}


def _sums(kern: types.ModuleType, x: np.ndarray, J: int, layout: tuple[int, int, int] | None,
          threads: int | None) -> np.ndarray:
    return Workspace(x.size, J, *(layout or ())).sums(x, J, threads, kern=kern)


def _check(kern: types.ModuleType, threads: int | None) -> None:
    for i, ((T, J, layout, kind), want) in enumerate(FROZEN.items()):
        got = _sums(kern, signal(T, kind, i), J, layout, threads)
        expected = np.array([float.fromhex(v) for v in want.split()])
        assert expected.size == J
        moved = np.flatnonzero(got != expected) + 1
        assert moved.size == 0, f"T={T} J={J} layout={layout} {kind}: levels {moved.tolist()} moved"


@needs_c_kernel
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_c_kernel_gives_the_frozen_bits(threads: int) -> None:
    from gmwm import _haar

    _check(_haar, threads)


def test_numba_kernel_gives_the_frozen_bits() -> None:
    from gmwm import _wvkernels

    _check(_wvkernels, None)


@pytest.mark.slow
@needs_c_kernel
def test_baseline_build_gives_the_frozen_bits(tmp_path: Path) -> None:
    # the installed kernel runs the AVX2 clone on a CPU that has it; this build has only the
    # baseline (SSE2 on x86-64) code, which other CPUs run
    cc = (sysconfig.get_config_var("CC") or "cc").split()
    so = tmp_path / f"_haar{sysconfig.get_config_var('EXT_SUFFIX')}"
    cmd = [*cc, "-O3", "-ffp-contract=off", "-DGMWM_HAAR_NO_CLONES", "-shared", "-fPIC",
           *([] if os.name == "nt" else ["-pthread"]),
           f"-I{sysconfig.get_paths()['include']}", "-o", str(so), str(SRC)]
    subprocess.run(cmd, check=True, capture_output=True)
    spec = spec_from_file_location("_haar", so, loader=ExtensionFileLoader("_haar", str(so)))
    assert spec is not None
    module = module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    for threads in (1, 2):
        _check(module, threads)


#: wvar's WV (float.hex) of float32 input (converted to float64 at the boundary) and of a drift
FROZEN_WVAR = {
    (70001, "rw", 99, "float32"):
        "0x1.0d0c76aabea3cp-1 0x1.b4c35b03a6620p-2 0x1.d24823c15ae70p-2 0x1.20ef7d04d2323p-1 "
        "0x1.8cb167508eb81p-1 0x1.255abdae5f984p+0 0x1.af59b6c4eb274p+0 0x1.3527d65cbec6ap+1 "
        "0x1.023957ca11052p+2 0x1.f58d1e28834acp+2 0x1.fb4d4810f004fp+3 0x1.14c3d4e9aa47ep+5 "
        "0x1.3591491e94da8p+6 0x1.18efffa8f8157p+7 0x1.a6d6a0d83be29p+7",
    (70001, "drift", 98, "float64"):
        "0x1.5400eeb23872dp-5 0x1.564ae968a4504p-6 0x1.5947e8d799a91p-7 0x1.50573ab88c79ep-8 "
        "0x1.4e4d0e1e94496p-9 0x1.51081deb3eafep-10 0x1.816f7f899e179p-11 0x1.12f4f269c15b9p-11 "
        "0x1.5332c3c7a291cp-11 0x1.5ec451db5cbbdp-10 0x1.d8d88fb03515fp-9 0x1.81a37e7e0c573p-7 "
        "0x1.53e3115a7d173p-5 0x1.3049830e4a82ap-3 0x1.1582efa13aff4p-1",
}


def test_wvar_gives_the_frozen_bits() -> None:
    for (T, kind, seed, dtype), want in FROZEN_WVAR.items():
        got = wvar(signal(T, kind, seed).astype(dtype)).variance
        np.testing.assert_array_equal(got, [float.fromhex(v) for v in want.split()])
