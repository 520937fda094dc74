"""``python -m silodem``: the same as the ``silodem`` command."""

from silodem.cli import main

if __name__ == "__main__":
    main()
