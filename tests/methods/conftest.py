"""The method tests mirror methods/: one folder per family (kalman/, pem/, pll/, peers/), the registry's and
fft's tests here. ``_signals`` (the test signals the families share) is importable from every folder."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
