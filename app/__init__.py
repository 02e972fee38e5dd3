"""Scanlight: relight a CG asset with the light of a scanned room (HDR expansion + PBGI)."""

__version__ = "0.1.0"
