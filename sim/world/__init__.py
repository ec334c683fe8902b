"""The world a trial happens in: the maze or the goal arena, the objects placed in it, and the
MuJoCo model built from them (maze.py, maze_gen.py, arena.py, arena_path.py, placement.py,
world.py)."""
