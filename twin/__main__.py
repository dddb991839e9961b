"""``python -m twin``: the same as the ``pnp-twin`` command."""

from twin.cli import main

if __name__ == "__main__":
    main()
