"""The job layer: TOML job files and the command line on top of the library.

* :mod:`~pymorembs.job.schema` -- the job file: tables, keys, their checks (``load_job``);
* :mod:`~pymorembs.job.run` -- running a job: model, frame, reductions, errors, summary and
  provenance, outputs (``run_job``);
* :mod:`~pymorembs.job.time_domain_checks` -- the time-domain and multibody checks of a job;
* :mod:`~pymorembs.job.cli` -- the ``pymorembs`` command.

The job layer imports only the public surface of the library (``docs/api.md``, "The public
surface": :mod:`pymorembs` and the ``__all__`` of the public subpackages), and nothing below
this package knows that a job file exists; a script uses :mod:`pymorembs` itself.
"""
