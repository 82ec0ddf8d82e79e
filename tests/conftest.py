"""Suite-wide settings.

Entry-point autoloading is switched off, so third-party plugins installed on
the machine cannot change results; built-in plugins are still registered.
Matplotlib draws off-screen.
"""

import os

os.environ["SEATKIT_DISABLE_PLUGIN_AUTOLOAD"] = "1"
os.environ.setdefault("MPLBACKEND", "Agg")
