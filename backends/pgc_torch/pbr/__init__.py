"""Fast PBR shading in torch: environment light over a direction set, ray-cast visibility, shared BRDF maths."""
