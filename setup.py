# setuptools needs setup() for cffi_modules; all other metadata is in pyproject.toml.
from setuptools import setup

setup(cffi_modules=["host/snakebot/_core_build.py:ffibuilder"])
