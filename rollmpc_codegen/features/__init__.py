"""Model options that augment a mode before or after condensing: disturbance models
(offset-free), the previous input (Δu weighting and bounds), move blocking, soft output bounds
and run-time bounds. Each module owns one YAML feature end to end (docs/features.md)."""
