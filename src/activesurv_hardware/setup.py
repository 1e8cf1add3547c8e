from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_hardware'

setup(
    name=package_name,
    version='0.9.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'A real rig: the hardware file, the camera driver (OpenCV VideoCapture) and the '
        'xy table path runner.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'camera = activesurv_hardware.camera_node:main',
            'table_runner = activesurv_hardware.table_runner_node:main',
        ],
    },
)
