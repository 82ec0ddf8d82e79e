"""``seatkit serve``: design a support interactively in the browser.

:mod:`seatkit.serve.designer` keeps the warm state and runs designs (one at
a time, newer requests superseding older ones); :mod:`seatkit.serve.app` is
the Starlette app (the page in ``static/``, three.js vendored in
``static/vendor/``, the JSON API). docs/serve.md describes the page and the
API. Starlette and uvicorn come with the ``serve`` extra
(``pip install 'seatkit[serve]'``).
"""

from __future__ import annotations

__all__ = ["create_app", "Designer"]


def __getattr__(name):
    if name == "create_app":
        from seatkit.serve.app import create_app

        return create_app
    if name == "Designer":
        from seatkit.serve.designer import Designer

        return Designer
    raise AttributeError(name)
