"""The bottom floor: infrastructure every package may import (it imports nothing of the project)."""
