"""The command line ``stripaero``: parse, call the library, print.

Each command is one module (:mod:`.run`, :mod:`.check`, :mod:`.simulate`,
:mod:`.importer`); :mod:`.options` holds the shared options and the one-line
messages; :mod:`.main` the group.  No rule of the method lives here.
"""
