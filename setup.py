"""Build of the optional C kernel; everything else is configured in pyproject.toml."""

from setuptools import Extension, setup

# gmwm/_haar.c is the C twin of the classical WV kernel. Optional: without a C compiler the install
# still succeeds and gmwm.wv uses the Numba kernel. -ffp-contract=off: a fused multiply-add would
# change the bits the two kernels share.
setup(ext_modules=[Extension("gmwm._haar", sources=["src/gmwm/_haar.c"],
                             extra_compile_args=["-O3", "-ffp-contract=off"], optional=True)])
