"""The one exception type for mistakes a user can make (bad scene keys, missing meshes, bad numbers).

Its message names the file, the key and the fix; the command line prints it on one line (a file's
several problems: one line each, `UserError.several`) and exits with status 2.
"""


class UserError(Exception):
    """A problem in the user's input, with a one-line message that says how to fix it; `several` makes
    one for a file with several problems: `lines` holds a first line that counts them, then one each."""

    lines: list[str] | None = None

    @classmethod
    def several(cls, head: str, problems: list[str], limit: int) -> "UserError":
        more = f" (the first {limit} shown)" if len(problems) > limit else ""
        exc = cls("\n".join(lines := [head + more, *problems[:limit]]))
        exc.lines = lines
        return exc


def counted(n: int, one: str, many: str | None = None) -> str:
    """`n` and the noun in the number it takes: "1 entry", "2 entries" (`many` defaults to one + "s")."""
    return f"{n} {one if n == 1 else many or one + 's'}"
