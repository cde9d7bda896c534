"""omninav: indoor localisation from panoramic vision (Hu, Zhu & Zhang), engine package."""

__version__ = "0.1.0"
