"""Build of the compiled replay kernel (the rest of the project is declared in pyproject.toml)."""

from Cython.Build import cythonize
from setuptools import Extension, setup

KERNEL = ["_text", "_engine", "_words", "_json", "_logline"]

setup(
    ext_modules=cythonize(
        [Extension(f"replay.kernel.{name}", [f"replay/kernel/{name}.pyx"]) for name in KERNEL],
        language_level=3,
    )
)
