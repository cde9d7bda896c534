"""omninav: indoor localisation from panoramic vision (Hu, Zhu & Zhang), engine package."""

import os as _os

# FFmpeg (inside OpenCV) logs to stderr on its own, e.g. "moov atom not found" for a broken file;
# we report such problems ourselves in one clear line, so keep its log quiet unless asked for.
_os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
_os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

__version__ = "0.1.0"
