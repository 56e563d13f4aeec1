"""The project's exception types.

Every error a user can provoke with bad input is one of these, with a message that
names the file or field at fault and what was expected (DESIGN.md, "Errors").
They subclass ``ValueError`` so that generic callers that catch bad values still work.
"""

from __future__ import annotations


class AcousticSimError(ValueError):
    """Base class of every error raised on purpose by acoustic-sim."""


class ConfigError(AcousticSimError):
    """A configuration value is out of range, of the wrong type, or inconsistent."""


class HRTFError(AcousticSimError):
    """An HRTF set (SOFA file or name) cannot be loaded or used."""


class SoundError(AcousticSimError):
    """A sound (name, WAV file or generator argument) cannot be produced or read."""


class RoomError(ConfigError):
    """A room specification (preset name, dimensions, RT60, positions) is invalid."""
