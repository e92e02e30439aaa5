"""File formats. Each reader validates and names the file and field at fault; each writer is atomic.

``capture`` (transforms.json directories) with ``capture_checks`` (captures that read without error but
that nothing can be reconstructed from), ``colmap`` (sparse models), ``gaussians_ply`` (3DGS .ply and the mesh-bound
variant), ``mesh`` (OBJ/PLY/glTF), ``images`` (PNG/EXR, sRGB <-> linear, environment maps), ``asset`` (the
garment asset directory), ``motion`` (a user's body motion: npz or a folder of OBJ frames), ``export`` (glTF,
USD, PLY/OBJ sequences), ``atomic`` (temp file + rename; the output path checks ``write_target`` and
``ensure_folder``), ``limits`` (the bounds on what an untrusted file may make PGC read or parse, and the
limited JSON/TOML readers ``read_json``/``read_toml``), ``lock`` (the output folder lock), ``timings``
(timings.json), ``light_record`` (the light a run was rendered and evaluated under). Layouts: docs/conventions.md.
"""
