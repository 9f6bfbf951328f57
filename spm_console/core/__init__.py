"""Pure computational core: no UI, no I/O, no serial. Radians inside, degrees at the edges."""
