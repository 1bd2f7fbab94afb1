"""The vehicle-track dynamics model: track input, contact, equations, simulation."""
