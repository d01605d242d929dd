"""The one base of errors a user can fix (a bad scenario, parameter, name or profile): the CLI prints their
one-line message and exits 2. Any other exception is a bug and is reported as an internal error."""


class UserError(ValueError):
    """A mistake in what the user asked for; the message is one line and names the fix."""


def one_line(text: str) -> str:
    """`text` safe to print as one terminal line: line breaks become spaces and other control characters
    (escape sequences from a file name or a file's text) their `\\xNN` escapes."""
    text = " ".join(text.splitlines())
    return "".join(c if c.isprintable() or c == " " else repr(c)[1:-1] for c in text)
