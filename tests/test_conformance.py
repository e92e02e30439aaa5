"""The built-in (and every installed) implementation runs its role's conformance suite.

Implementations come from the installed entry points; an unavailable one (missing extra) is not
collected. A role with no available implementation shows as a skip with pytest's "empty parameter set";
an implementation that cannot be built from its default options (a required file path, a missing model
file) is skipped with the builder's message, so both stay visible in the summary.
"""

from __future__ import annotations

import pytest

from pgc.errors import PGCConfigError, PGCDataError
from pgc.registry import Registry
from pgc.testing.conformance import (AlbedoEstimatorConformance, BRDFConformance, CalibratorConformance,
                                     FilterConformance, MetricConformance, PBRRendererConformance,
                                     ReconstructorConformance, SceneRendererConformance, SimulatorConformance,
                                     SplatRendererConformance)

REGISTRY = Registry.discover()

def _available(role: str) -> list:
    return [pytest.param(impl, id=impl.name) for impl in REGISTRY.list(role) if impl.available]


@pytest.fixture(scope="module")
def required_options(tmp_path_factory) -> dict:
    """Options that an implementation cannot do without (a user's scan file for the 'mesh' reconstructor)."""
    from pgc.io.mesh import write_mesh
    from pgc.testing.conformance import uv_sphere

    scan = tmp_path_factory.mktemp("scan") / "scan.obj"
    write_mesh(scan, uv_sphere())
    return {("reconstructor", "mesh"): {"path": str(scan)}}


@pytest.fixture(scope="module")
def built(required_options):
    """Implementations are built once per module (some compile native libraries on first use)."""
    cache: dict = {}

    def get(impl):
        key = (impl.role, impl.name)
        if key not in cache:
            try:
                cache[key] = impl.create(required_options.get(key))
            except (PGCConfigError, PGCDataError) as exc:  # e.g. a required option such as a file path
                cache[key] = exc
        if isinstance(cache[key], Exception):
            pytest.skip(f"{impl.role} '{impl.name}' cannot be built with its default options: {cache[key]}")
        return cache[key]

    return get


class TestFilterImplementations(FilterConformance):
    @pytest.fixture(params=_available("filter"))
    def implementation(self, request, built):
        return built(request.param)


class TestMetricImplementations(MetricConformance):
    @pytest.fixture(params=_available("metric"))
    def implementation(self, request, built):
        return built(request.param)


class TestBRDFImplementations(BRDFConformance):
    @pytest.fixture(params=_available("brdf"))
    def implementation(self, request, built):
        return built(request.param)


@pytest.mark.slow
class TestSimulatorImplementations(SimulatorConformance):
    @pytest.fixture(params=_available("simulator"))
    def implementation(self, request, built):
        return built(request.param)


@pytest.mark.slow
class TestSplatRendererImplementations(SplatRendererConformance):
    @pytest.fixture(params=_available("splat_renderer"))
    def implementation(self, request, built):
        return built(request.param)


class TestAlbedoEstimatorImplementations(AlbedoEstimatorConformance):
    @pytest.fixture(params=_available("albedo_estimator"))
    def implementation(self, request, built):
        return built(request.param)


@pytest.mark.slow
class TestPBRRendererImplementations(PBRRendererConformance):
    @pytest.fixture(params=_available("pbr_renderer"))
    def implementation(self, request, built):
        return built(request.param)


@pytest.mark.slow
class TestReconstructorImplementations(ReconstructorConformance):
    @pytest.fixture(params=_available("reconstructor"))
    def implementation(self, request, built):
        return built(request.param)


class TestSceneRendererImplementations(SceneRendererConformance):
    @pytest.fixture(params=_available("scene_renderer"))
    def implementation(self, request, built):
        return built(request.param)


class TestCalibratorImplementations(CalibratorConformance):
    @pytest.fixture(params=_available("calibrator"))
    def implementation(self, request, built):
        return built(request.param)
