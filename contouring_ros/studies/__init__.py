"""Studies over many in-process runs: sweeps, learning passes, tuning, the benchmark, the papers' claims.

- :mod:`.sweep`: every combination of a grid, batched,
- :mod:`.learning`: the passes of an ILC experiment,
- :mod:`.search`, :mod:`.tuning`: the batched global search and the fair tuning of a method's gains (its
  protocol and records), in steps: :mod:`.machine` (the realistic machine and its draws), :mod:`.gains`,
  :mod:`.outcomes` (the runs and their figures), :mod:`.loops` (linear loops, margins, Ms), :mod:`.space` (the
  tuning space), :mod:`.objective` (its penalties), :mod:`.tuner` (the searches), :mod:`.summaries` (intervals),
- :mod:`.benchmark`: every estimator and controller tuned alike on every paper scenario; :mod:`.benchmark_parts`:
  its runs saved, read back and merged; :mod:`.benchmark_report`, :mod:`.benchmark_figures`: its report,
- :mod:`.parts`, :mod:`.checkpoints`: a benchmark's saved parts and the rows kept as they finish,
- :mod:`.claims_file`, :mod:`.claims`, :mod:`.claims_maps`, :mod:`.claims_report`: each paper's claims file and
  verdict rules, the claims measured, their regime maps, their report,
- :mod:`.readings`, :mod:`.paper`: each paper's open readings, its report,
- :mod:`.executors`: local processes or a Dask cluster that run them.

Nothing is imported here."""
