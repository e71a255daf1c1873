"""`python -m linecloud ...` (and the `linecloud` script pip installs): the command-line tool
built with the package, with the same arguments."""

import os
import sys

from linecloud import cli_path


def main() -> None:
    tool = cli_path()
    os.execv(tool, [tool, *sys.argv[1:]])


if __name__ == "__main__":
    main()
