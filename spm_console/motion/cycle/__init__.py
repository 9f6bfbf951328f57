"""The servo loop's cycles under the executor: the state they share, their transactions on
the bus (set-up, each cycle's write and read, the hardware poll, release) and the stops."""
