"""Where results go: result sinks (HDF5, memory), the reader, the validity checks written with a
run, and the run/resume/lock orchestration.

    sinks       HDF5 and in-memory sinks, checkpoints
    reader      one read interface for files and memory
    validity    validity warnings written into a finished result
    run         running a scenario into a file: checkpoints, resume, locks
"""
