"""Shared fixtures for the tiling tests (imported by tests/test_tiling_*.py)."""
import pytest


@pytest.fixture(scope="session")
def graph():
    from authoring.default_library import ensure_library
    from runtime.motion.graph import MotionGraph
    return MotionGraph.load(ensure_library("default", log=lambda *a: None, progress=False))


@pytest.fixture(scope="session")
def singles(graph):
    from runtime.tiling.patch import single_character_patches
    return single_character_patches(graph)


@pytest.fixture(scope="session")
def meet_library(graph, singles):
    from runtime.tiling.synthetic import synthetic_library
    return synthetic_library(graph, meets=2, singles=singles)


@pytest.fixture(scope="session")
def prepared(meet_library):
    from runtime.tiling.prepared import PreparedLibrary
    return PreparedLibrary(meet_library)
