"""Built-in albedo estimator: the model-free shading-ratio baseline (numpy)."""

from pgc.registry import ImplementationSpec

SPECS = [
    ImplementationSpec(
        role="albedo_estimator", name="shading_ratio",
        factory="pgc.albedo.shading_ratio:ShadingRatioEstimator",
        options="pgc.albedo.shading_ratio:ShadingRatioOptions",
        description="model-free baseline: image / white-albedo shading of the mesh under the fitted light"),
]
