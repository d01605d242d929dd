"""The one base of errors a user can fix (a bad scenario, parameter, name or profile): the CLI prints their
one-line message and exits 2. Any other exception is a bug and is reported as an internal error."""


class UserError(ValueError):
    """A mistake in what the user asked for; the message is one line and names the fix."""
