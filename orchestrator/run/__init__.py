"""One run: driver, runner, results folder, history, checkpoints, progress, signals, field output, plots, analyses."""
