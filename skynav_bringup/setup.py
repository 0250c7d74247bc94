from glob import glob

from setuptools import find_packages, setup

package_name = 'skynav_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.xml') + glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='skynav developers',
    maintainer_email='skynav@example.org',
    description='Launch files, default parameters, bag tools and the skynav command line.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['skynav = skynav_bringup.cli:entry'],
        'skynav.commands': [
            'demo = skynav_bringup.cli.demo',
            'echo = skynav_bringup.cli.echo',
            'eval = skynav_bringup.cli.evaluate',
            'info = skynav_bringup.cli.info',
            'launch = skynav_bringup.cli.launch',
            'record = skynav_bringup.cli.record',
            'replay = skynav_bringup.cli.replay',
            'run = skynav_bringup.cli.run',
        ],
    },
)
