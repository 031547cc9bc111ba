"""Safety Gym replica in pymunk (Point/Car/Mass x Goal/Button/Push, levels 0-2)."""
