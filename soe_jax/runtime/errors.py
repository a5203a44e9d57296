"""`UserError`: a mistake in what the user asked for (a name, a count, a file, a config that does not
match its run directory). The commands print its message on one line and exit with status 2;
anything else keeps its traceback."""


class UserError(ValueError):
  pass
