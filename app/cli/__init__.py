"""Command line: ``./vpcontact run CASE.yaml`` (the launcher; ``python -m vpcontact`` in the
project's environment, or its ``vpcontact`` console script, are the same).

Arguments of the form ``-snes_rtol 1e-12`` / ``-ksp_view`` (one leading dash) are PETSc
options: they are passed unchanged to PETSc under our prefix (``vpcontact_``) and override
the case file's ``petsc`` section.  Exit codes: 0 done, 1 solver failure, 2 bad input,
3 interrupted.

- ``main``: the entry point (parse, take the signals, dispatch, last-resort error handling);
- ``parser``: the argparse grammar and the PETSc-option split;
- ``commands``: one ``cmd_<name>`` per command;
- ``outdir``: output directories (which files are ours, the lock, preparation);
- ``logs``: the run log on stdout;
- ``checkrun``: the reports of ``check`` and ``info``; ``progress``: the progress bar;
  ``streams``: standard streams that never stop a run.

The one printer of error, warning and interruption lines and the exit codes are
app/io/messages.py; the process's start-up and exit costs app/startup.py.
"""
