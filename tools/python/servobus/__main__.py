"""python3 -m servobus: the servoctl command line."""
import sys

from .cli import main

sys.exit(main())
