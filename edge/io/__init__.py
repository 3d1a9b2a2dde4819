"""I/O: MCAP recordings (`edge.io.mcap`) and the zenoh key space (`edge.io.zenoh`).

Submodules are imported explicitly (``from edge.io.mcap import Recorder``) so that importing one
does not pull in the other's dependencies.
"""
