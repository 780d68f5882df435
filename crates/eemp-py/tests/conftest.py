import warnings

import pytest


@pytest.fixture(autouse=True)
def _quiet_space_warnings():
    # gymnasium's checker advises normalised, bounded spaces; the tasks' spaces are what the
    # Rust tasks take (joint-target offsets up to ±5, squashed EEMP-RL actions, raw observations).
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*Box (action|observation) space.*")
        warnings.filterwarnings("ignore", message=".*symmetric and normalized.*")
        yield
