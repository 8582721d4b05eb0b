"""``python -m snakebot`` and the ``snakebot`` script: the CLI, with Ctrl-C during the
imports (a second or so on a loaded machine) reported in one line, not a traceback."""

import sys


def run() -> None:
    try:
        from snakebot.cli import main
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        sys.exit(130)
    main()


if __name__ == "__main__":
    run()
