"""``python -m pnp_twin``: the same as the ``pnp-twin`` command."""

from pnp_twin.cli import main

if __name__ == "__main__":
    main()
