"""The operator console (Textual). ``make_app`` in :mod:`spm_console.tui.app` builds it.

:mod:`spm_console.services.session` holds the state and blocking operations and has no
Textual import (the headless script runner uses it too).
"""
