"""How to drive: the engines that integrate a prepared scenario into a result sink.

    full           the full-resolution drive, block by block (Drive)
    multiscale     ride windows of the real road, slow states advanced between them
    time_parallel  the drive split in time over processes, joined by a slow-state correction
    ensemble       many full drives in lockstep on one vector step (lanes across cases)
"""
