"""The browser side of a study: participant display, operator console and questionnaires.

``bowden serve`` runs it (:func:`bowden.web.server.serve`). Needs the ``web`` extra (starlette,
uvicorn, websockets); every page and script is a file of this package, nothing is fetched from
elsewhere. See ``docs/web.md``.
"""
