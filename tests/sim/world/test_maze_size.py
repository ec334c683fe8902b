"""A maze file is held to the generator's cap, MAX_MAZE_SIDE cells a side, with one line naming
the file and its size (a 64 x 64 file used to be taken and had not set up after 200 s; larger
ones had no limit at all)."""

import pytest

from sim.world.maze import MAX_MAZE_SIDE, MazeFormatError, load_maze, parse_maze


def _open_maze(rows: int, cols: int) -> str:
    """A maze with the outer boundary only: (2 * rows + 1) lines of 4 * cols + 1 characters."""
    top = "+" + "---+" * cols
    inner = "+" + "   +" * cols
    cells = "|" + "    " * (cols - 1) + "   |"
    lines = [top] + [line for r in range(rows) for line in (cells, inner if r < rows - 1 else top)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("rows", "cols"), [(MAX_MAZE_SIDE + 1, 2), (2, MAX_MAZE_SIDE + 1), (500, 500)])
def test_a_maze_file_over_the_cap_is_one_line_naming_the_file_and_its_size(tmp_path, rows, cols):
    path = tmp_path / "big.maze"
    path.write_text(_open_maze(rows, cols))
    with pytest.raises(MazeFormatError) as info:
        load_maze(path)
    assert str(info.value) == (
        f"{path}:1:1: the maze is {rows}x{cols} cells; expected at most {MAX_MAZE_SIDE}x{MAX_MAZE_SIDE}"
    )


def test_a_maze_at_the_cap_is_read():
    m = parse_maze(_open_maze(MAX_MAZE_SIDE, MAX_MAZE_SIDE), "cap.maze")
    assert (m.rows, m.cols) == (MAX_MAZE_SIDE, MAX_MAZE_SIDE)
