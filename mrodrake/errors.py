"""User-facing errors: one line naming the field path or formula position; the CLI exits with status 2."""


class UserError(Exception):
    """A problem with user input (scenario file, formula, options); never a bug in mrodrake.

    The message is a single line that names where the problem is (a scenario field path such as
    ``robots[1].mass`` or a formula column).  The CLI prints it as ``error: <message>`` and exits 2.
    """

    def __init__(self, message: str):
        if "\n" in message:
            first, _, rest = message.partition("\n")
            self.detail = rest
            message = first
        else:
            self.detail = ""
        super().__init__(message)


class NoPlanFound(UserError):
    """A planner's budget ran out before a plan was found and satisfiability is undecided (CLI exit status 3)."""

    exit_status = 3
