"""pinarray: drive a servo pin-array tactile stimulator and run experiments on it."""

__version__ = "0.1.0"
