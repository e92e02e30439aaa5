"""File formats. Each reader validates and names the file and field at fault."""
