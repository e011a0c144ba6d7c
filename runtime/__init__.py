"""Infrastructure every other package may use, and which imports no science package.

* :mod:`runtime.atomic` — write-to-temporary-then-rename, probes for writable folders;
* :mod:`runtime.publish` — an output folder published as one unit (lock, stage, journal, signals);
* :mod:`runtime.cliargs` — argument parsing with one-line errors and the common ``main`` of the commands;
* :mod:`runtime.validation` — input checks at the API entry points (real, finite arrays and scalars).

POSIX only: output locking uses ``fcntl.flock``.
"""
