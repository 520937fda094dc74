"""``python -m silodem``: the same as the ``silodem`` command."""

from silodem.launcher import main

if __name__ == "__main__":
    main()
