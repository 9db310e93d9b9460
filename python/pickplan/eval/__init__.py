"""Evaluation: the paper tables as sweeps (local process pool or Ray, resumable), baselines, the demo."""
