"""Where results go: result sinks (HDF5, memory), the reader, the validity checks written with a
run, and the run/resume/lock orchestration.

    layout        the results file's layout on the writing side, safe temporary paths, a write that found no room
    results_file  DriveFile: the one owner of a results file's life cycle (create, append, finish, status, resume)
    sinks         HDF5 and in-memory sinks
    reader        one read interface for files and memory
    validity      validity warnings written into a finished result
    run           running a scenario into a file: cancellation, resume, locks
"""
