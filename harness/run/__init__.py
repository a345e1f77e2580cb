"""Computing cells: one execution path, the result cache with its claim / lock / re-read protocol, worker
processes, work and time limits, interrupts, and the calibration that runs cells to fit parameters."""
