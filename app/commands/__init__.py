"""The ``storybeam`` commands: one module ``<name>_cmd.py`` per command, each defining
``register(subparsers)``. :mod:`app.cli` finds them with :mod:`pkgutil`, so adding a
command is adding a file; a module that cannot be imported is reported as an error, not
skipped. Heavy imports (Kivy, OpenCV, pyrender, the bench and stress harnesses) are
deferred into each command's ``run`` so ``storybeam --help`` stays quick."""
