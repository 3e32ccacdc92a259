"""Learning the deflection: datasets and model files, where to sample, the predictors, training,
the model's health and its refresh (pure: no rclpy)."""
