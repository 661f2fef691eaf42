"""The one exception type for mistakes a user can make (bad scene keys, missing meshes, bad numbers).

Its message names the file, the key and the fix; the command line prints it on one line and exits
with status 2.
"""


class UserError(Exception):
    """A problem in the user's input, with a one-line message that says how to fix it."""


def counted(n: int, one: str, many: str | None = None) -> str:
    """`n` and the noun in the number it takes: "1 entry", "2 entries" (`many` defaults to one + "s")."""
    return f"{n} {one if n == 1 else many or one + 's'}"
