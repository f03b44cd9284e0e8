import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
EXAMPLES = os.path.join(ROOT, "crates", "python", "examples")
sys.path.insert(0, EXAMPLES)


@pytest.fixture
def fixtures():
    return os.path.join(ROOT, "fixtures", "scenes")


@pytest.fixture
def slope():
    return os.path.join(EXAMPLES, "slope.json")
