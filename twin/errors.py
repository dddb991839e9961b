"""The one error family the command line turns into a one-line message and exit code 2."""


class UserError(ValueError):
    """A user mistake (bad file, bad value, unknown name); ``str(e)`` is one clear line."""
