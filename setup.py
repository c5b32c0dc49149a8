"""Build of the optional C kernel and of the Numba kernels' cache; the rest is in pyproject.toml."""

import os
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class BuildKernels(build_ext):
    """Build the C kernel, then compile the Numba kernels into Numba's cache next to the built
    package (``gmwm/__pycache__``), so that the first command after installation does not
    compile (why: ``gmwm/_precompile.py``). ``GMWM_NO_PRECOMPILE=1`` skips the second step; a
    failure there only warns (the kernels then compile on first use, with a note on stderr)."""

    def run(self) -> None:
        super().run()
        if os.environ.get("GMWM_NO_PRECOMPILE", "").strip() not in ("", "0"):
            print("gmwm: GMWM_NO_PRECOMPILE set: the Numba kernels compile on first use")
            return
        # where the package is being built: in place (editable installs) or in build_lib
        root = Path("src") if self.inplace or getattr(self, "editable_mode", False) \
            else Path(self.build_lib)
        if not (root / "gmwm" / "_precompile.py").exists():
            root = Path("src")
        env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root.resolve()),
                                                          env.get("PYTHONPATH")]))
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env["GMWM_NUM_THREADS"] = env.get("GMWM_NUM_THREADS", "1")
        proc = subprocess.run([sys.executable, "-m", "gmwm._precompile"], env=env, check=False)
        if proc.returncode != 0:
            print("gmwm: WARNING: compiling the Numba kernels at install failed; they will "
                  "compile on first use (a note on stderr says so)")


# gmwm/_haar.c is the C twin of the classical WV kernel. Optional: without a C compiler the install
# still succeeds and gmwm.wv uses the Numba kernel. -ffp-contract=off: a fused multiply-add would
# change the bits the two kernels share.
# (several threads: POSIX threads where there are some).
_THREADS = [] if os.name == "nt" else ["-pthread"]
# gmwm/_wvcov.c is the C twin of gmwm.wvcov's Numba kernels (same conditions, same reason for the
# flag), so that `gmwm plan` does not load Numba.
setup(ext_modules=[Extension("gmwm._haar", sources=["src/gmwm/_haar.c"],
                             extra_compile_args=["-O3", "-ffp-contract=off", *_THREADS],
                             extra_link_args=_THREADS, optional=True),
                   Extension("gmwm._wvcov", sources=["src/gmwm/_wvcov.c"],
                             extra_compile_args=["-O2", "-ffp-contract=off"], optional=True)],
      cmdclass={"build_ext": BuildKernels})
