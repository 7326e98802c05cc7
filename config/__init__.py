"""Network files and node defaults shipped with openptrack_py (``openptrack_py.presets``)."""
