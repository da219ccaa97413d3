"""One exception root for the core, with messages that say what was wrong and what would
be right."""


def cut_text(message: str, limit: int) -> str:
    """`message` as an answer quotes it: cut to `limit` characters with a note of how many more
    there were (a goal's setting may hold a 100 kB string)."""
    if len(message) <= limit:
        return message
    return f"{message[:limit]} ... ({len(message) - limit} more characters)"


class RearrangementError(Exception):
    """Base class of every error the core raises on purpose."""


class RobotModelError(RearrangementError):
    """A robot URDF or robot config is missing, malformed or inconsistent."""


class SceneError(RearrangementError):
    """A scene is malformed. `field` is the dotted path of the offending field (e.g.
    ``objects[1].pose``) and `problem` says what is wrong with it."""

    def __init__(self, field: str, problem: str):
        self.field = field
        self.problem = problem
        super().__init__(f"{field}: {problem}" if field else problem)


class InputError(RearrangementError):
    """A planning input (joint state, object poses, goal, parameter) is unusable. `field` names
    the offending field (e.g. ``joint_states.position[joint3]``), `problem` says why."""

    def __init__(self, field: str, problem: str):
        self.field = field
        self.problem = problem
        super().__init__(f"{field}: {problem}" if field else problem)


class ObjectTilted(InputError):
    """An object seen tilted from upright further than the bound the reader was given: the
    planner models upright prisms only, and an object that tilts has begun to tip (the
    closed loop's watch stops the arm on it)."""

    def __init__(self, field: str, object_id: str, tilt: float, bound: float):
        self.object_id, self.tilt, self.bound = object_id, tilt, bound
        super().__init__(field, f"of object '{object_id}' is tilted by {tilt:.3f} rad (more "
                                f"than {bound:g} rad); objects must stand upright on the table")
