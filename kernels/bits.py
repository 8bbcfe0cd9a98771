"""Two arrays' bytes compared where they live (``core.graphs``' check of a captured step against
the same step launched plainly), so that the check reads one flag rather than every array."""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def differ(a: wp.array(dtype=wp.uint8), b: wp.array(dtype=wp.uint8), flag: wp.array(dtype=wp.int32)):
    """flag[0] = 1 where the bytes a[i] and b[i] differ, left as it is elsewhere (every thread
    that writes writes 1: no race on the value). Dim len(a)."""
    i = wp.tid()
    if a[i] != b[i]:
        flag[0] = 1
