"""Model profiles for tests that need a trained bank but not a good one (not a test module)."""

from acoustic_sim.auditory.ssdenet import SSDENetProfile

TINY = SSDENetProfile(name="tiny", hidden=8, bins=(20, 120, 400), sounds=4, epochs=1, batch_size=128, threads=1)
"""An SSDENet profile that trains in well under a second (determinism, checkpoints, refusals)."""
