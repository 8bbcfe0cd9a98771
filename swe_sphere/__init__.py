"""swe_sphere: spectral-element shallow-water model on the cubed sphere (HOMME/CAM-SE) in NVIDIA Warp."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("swe-sphere")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
