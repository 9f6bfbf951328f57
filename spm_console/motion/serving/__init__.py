"""The motion process's server, beside its request loop (:mod:`spm_console.motion.server`): the
answers to requests that move nothing, telemetry out of the servo loop, and the garbage
collector kept quiet while the wrist moves."""
