"""poi: the perception pipeline under test.

Frames in (RGB, aligned depth, intrinsics, tracker pose), a POI report out. This
package never imports ``sim`` or ``eval`` so a team can run it on a real robot's
frames.
"""
