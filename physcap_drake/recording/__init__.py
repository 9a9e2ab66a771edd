"""Recording runs to MCAP (written with foxglove-sdk, read with mcap) and episode folders."""
