"""File formats. Each reader validates and names the file and field at fault; each writer is atomic.

``capture`` (transforms.json directories), ``colmap`` (sparse models), ``gaussians_ply`` (3DGS .ply and the
mesh-bound variant), ``mesh`` (OBJ/PLY/glTF), ``images`` (PNG/EXR, sRGB <-> linear), ``asset`` (the garment
asset directory), ``motion`` (a user's body motion: npz or a folder of OBJ frames), ``atomic`` (temp file
+ rename). Layouts: docs/conventions.md.
"""
