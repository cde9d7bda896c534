"""The benchmarks: each module with a `main` is a script, run from the repository root as
`.venv/bin/python -m bench.NAME` (docs/benchmarks.md gives each one's command); `common` (the
machine, threads, baselines, timings), `venues` (the cached family venues and their answers),
`scoring` (how a source's clips are scored and judged) and `ablation` (the configurations since
the paper) are the library the scripts and the tests share.
"""
