"""Fixtures of the GetDP verification tests."""
import pytest


@pytest.fixture
def work(tmp_path):
    return tmp_path / "em"
